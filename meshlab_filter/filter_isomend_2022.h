/*
 * filter_isomend_2022.h - MeshLab 2021.05+ adapter (FilterPlugin API)
 *
 * The sibling of filter_isomend.h for the plugin API MeshLab uses since
 * 2021.05: FilterPlugin instead of MeshFilterInterface, const QAction*,
 * initParameterList() returning the list, applyFilter() returning a map and
 * throwing MLException on failure, pythonFilterName() for PyMeshLab.  The
 * parameter list, the parameter reading and the mesh copy are the same code
 * (filter_isomend_meshlab.h); the rest is in isomend_filter_job.{h,cpp}.
 *
 * Built when the installed MeshLab is 2021.05+, against its own headers, and
 * tested with MeshLab 2022.02 in Debian 13 (tests/meshlab/meshlab2022.cmake);
 * on Debian 12, ISOMEND_MESHLAB_NEW_API_CHECK compile-checks it.  MeshLab's
 * loader accepts only plugins built with its exact version and scalar type,
 * so a binary for a given MeshLab must be built against that MeshLab's
 * headers.
 */
#ifndef ISOMEND_FILTER_ISOMEND_2022_H
#define ISOMEND_FILTER_ISOMEND_2022_H

#include <common/plugins/interfaces/filter_plugin.h>

class FilterIsomendPlugin : public QObject, public FilterPlugin
{
    Q_OBJECT
    MESHLAB_PLUGIN_IID_EXPORTER(FILTER_PLUGIN_IID)
    Q_INTERFACES(FilterPlugin)

public:
    enum { FP_ISOSURFACE_FROM_STACK };

    FilterIsomendPlugin();

    QString pluginName() const override;
    QString filterName(ActionIDType filter) const override;
    QString pythonFilterName(ActionIDType filter) const override;
    QString filterInfo(ActionIDType filter) const override;
    FilterClass getClass(const QAction *a) const override;
    FilterArity filterArity(const QAction *a) const override;
    int getPreConditions(const QAction *a) const override;
    int postCondition(const QAction *a) const override;
    /* The MeshDocument overload: the default one dereferences md.mm(),
     * which is NULL in an empty document, where a create filter runs. */
    RichParameterList initParameterList(const QAction *a, const MeshDocument &md) override;
    std::map<std::string, QVariant> applyFilter(const QAction *a, const RichParameterList &par,
                                                MeshDocument &md, unsigned int &postConditionMask,
                                                vcg::CallBackPos *cb) override;

private:
    [[noreturn]] void fail(const QString &message) const;
};

#endif /* ISOMEND_FILTER_ISOMEND_2022_H */
