/*
 * filter_isomend_2022.cpp - MeshLab 2021.05+ adapter (see filter_isomend_2022.h)
 *
 * Failure contract as in the 2020.09 adapter: the reason is logged and thrown
 * as MLException (which MeshLab shows, and PyMeshLab raises); the layer is
 * created only after a successful extraction and removed if the copy fails.
 */
#include "filter_isomend_2022.h"

#include <common/mlexception.h>

#include <new>
#include <string>

#include "filter_isomend_meshlab.h"
#include "isomend_filter_job.h"

namespace job = isomend_filter;
using isomend_meshlab::qs;

FilterIsomendPlugin::FilterIsomendPlugin()
{
    typeList = {FP_ISOSURFACE_FROM_STACK};
    for (ActionIDType t : types())
        actionList.push_back(new QAction(filterName(t), this));
}

QString FilterIsomendPlugin::pluginName() const
{
    return "FilterIsomend";
}

QString FilterIsomendPlugin::filterName(ActionIDType filter) const
{
    return filter == FP_ISOSURFACE_FROM_STACK ? qs(job::kFilterName) : QString();
}

QString FilterIsomendPlugin::pythonFilterName(ActionIDType filter) const
{
    return filter == FP_ISOSURFACE_FROM_STACK ? QString("generate_isosurface_from_slice_stack")
                                              : QString();
}

QString FilterIsomendPlugin::filterInfo(ActionIDType filter) const
{
    return filter == FP_ISOSURFACE_FROM_STACK ? qs(job::kFilterInfo) : QString();
}

FilterPlugin::FilterClass FilterIsomendPlugin::getClass(const QAction *) const
{
    return FilterPlugin::MeshCreation;
}

FilterPlugin::FilterArity FilterIsomendPlugin::filterArity(const QAction *) const
{
    return NONE;
}

int FilterIsomendPlugin::getPreConditions(const QAction *) const
{
    return MeshModel::MM_NONE;
}

int FilterIsomendPlugin::postCondition(const QAction *) const
{
    return MeshModel::MM_NONE;
}

RichParameterList FilterIsomendPlugin::initParameterList(const QAction *a, const MeshDocument &)
{
    RichParameterList par;
    if (ID(a) == FP_ISOSURFACE_FROM_STACK)
        isomend_meshlab::fill_parameters(par);
    return par;
}

void FilterIsomendPlugin::fail(const QString &message) const
{
    log(GLLogStream::WARNING, ("isomend: error: " + message).toStdString());
    throw MLException(message);
}

std::map<std::string, QVariant> FilterIsomendPlugin::applyFilter(const QAction *a,
                                                                 const RichParameterList &par,
                                                                 MeshDocument &md,
                                                                 unsigned int &postConditionMask,
                                                                 vcg::CallBackPos *cb)
{
    if (ID(a) != FP_ISOSURFACE_FROM_STACK)
        wrongActionCalled(a);

    job::Job run;
    const bool ok = run.run(isomend_meshlab::read_parameters(par),
                            [cb](int percent, const char *stage) {
                                return cb ? cb(percent, stage) : true;
                            });
    for (const std::string &line : run.log_lines())
        log(line);
    if (!run.warning().empty()) /* slices not evenly spaced: meshed where they are */
        log(GLLogStream::WARNING, "isomend: warning: " + run.warning());
    if (!ok)
        fail(QString::fromStdString(run.error()));

    if (!run.labels().empty()) { /* a label map: a layer a label */
        if (!isomend_meshlab::add_label_layers(
                md, run, cb, [&md](MeshModel *m) { md.delMesh(m->id()); },
                [this](const std::string &line) { log(line); }))
            fail("out of memory while copying the labels into MeshLab");
        postConditionMask = MeshModel::MM_NONE;
        if (cb)
            cb(100, "isomend: done");
        return {{"labels", QVariant::fromValue<qulonglong>(run.labels().size())}};
    }
    MeshModel *m = md.addNewMesh("", QString::fromStdString(run.layer_name()), true);
    if (!m)
        fail("MeshLab could not create a new layer");
    try {
        isomend_meshlab::copy_mesh(run.mesh(), m->cm, cb, run.world_transform());
    } catch (const std::bad_alloc &) {
        md.delMesh(m->id());
        fail("out of memory while copying the mesh into MeshLab");
    }
    log("layer \"%s\": %d vertices, %d faces", qUtf8Printable(m->label()), m->cm.vn, m->cm.fn);
    postConditionMask = MeshModel::MM_NONE;
    if (cb)
        cb(100, "isomend: done");

    const isomend_stats &st = run.stats();
    return {{"vertices", QVariant::fromValue<qulonglong>(st.vertices)},
            {"triangles", QVariant::fromValue<qulonglong>(st.triangles)},
            {"table_triangles",
             QVariant::fromValue<qulonglong>(st.triangles_by_origin[ISOMEND_ORIGIN_TABLE])},
            {"durst_triangles",
             QVariant::fromValue<qulonglong>(st.triangles_by_origin[ISOMEND_ORIGIN_DURST])},
            {"mending_triangles",
             QVariant::fromValue<qulonglong>(st.triangles_by_origin[ISOMEND_ORIGIN_MEND])}};
}

MESHLAB_PLUGIN_NAME_EXPORTER(FilterIsomendPlugin)
