/*
 * filter_isomend.h - MeshLab 2020.09 adapter of "Isosurface from Slice Stack (isomend)"
 *
 * The MeshFilterInterface half of the filter: parameter list, progress
 * callback, Log(), and the copy of the isomend mesh into a new layer.  All the
 * rest (parameter meaning, validation, reading, extraction, log text) is in
 * isomend_filter_job.{h,cpp}, which knows nothing of MeshLab; an adapter for
 * MeshLab 2021.05+ (FilterPlugin) is a sibling of this file.
 *
 * Built against the headers of Debian's meshlab source package, with
 * MESHLAB_SCALAR=float (what Debian's binaries use).
 */
#ifndef ISOMEND_FILTER_ISOMEND_H
#define ISOMEND_FILTER_ISOMEND_H

#include <common/interfaces.h>

class FilterIsomendPlugin : public QObject, public MeshFilterInterface
{
    Q_OBJECT
    MESHLAB_PLUGIN_IID_EXPORTER(MESH_FILTER_INTERFACE_IID)
    Q_INTERFACES(MeshFilterInterface)

public:
    enum { FP_ISOSURFACE_FROM_STACK };

    FilterIsomendPlugin();

    QString pluginName() const override;
    QString filterName(FilterIDType filter) const override;
    QString filterInfo(FilterIDType filter) const override;
    FilterClass getClass(QAction *a) override;
    FILTER_ARITY filterArity(QAction *a) const override;
    int getPreConditions(QAction *a) const override;
    int postCondition(QAction *a) const override;
    /* The MeshDocument overload: the default one dereferences md.mm(),
     * which is NULL in an empty document, where a create filter runs. */
    void initParameterSet(QAction *a, MeshDocument &md, RichParameterList &par) override;
    bool applyFilter(QAction *a, MeshDocument &md, const RichParameterList &par,
                     vcg::CallBackPos *cb) override;

private:
    bool fail(const QString &message);
};

#endif /* ISOMEND_FILTER_ISOMEND_H */
