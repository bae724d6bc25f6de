/*
 * filter_isomend.cpp - MeshLab 2020.09 adapter (see filter_isomend.h)
 *
 * Failure contract: on any error the reason goes to errorMessage (the GUI
 * shows it) and to Log() (meshlabserver prints only the log, then "Problem
 * with filter" and exits 255); no layer is left behind.  The layer is created
 * only after a successful extraction, and removed again if copying the mesh
 * into it runs out of memory.
 */
#include "filter_isomend.h"

#include <new>
#include <string>

#include "filter_isomend_meshlab.h"
#include "isomend_filter_job.h"

namespace job = isomend_filter;
using isomend_meshlab::qs;

FilterIsomendPlugin::FilterIsomendPlugin()
{
    typeList << FP_ISOSURFACE_FROM_STACK;
    for (FilterIDType t : types())
        actionList << new QAction(filterName(t), this);
}

QString FilterIsomendPlugin::pluginName() const
{
    return "FilterIsomend";
}

QString FilterIsomendPlugin::filterName(FilterIDType filter) const
{
    return filter == FP_ISOSURFACE_FROM_STACK ? qs(job::kFilterName) : QString();
}

QString FilterIsomendPlugin::filterInfo(FilterIDType filter) const
{
    return filter == FP_ISOSURFACE_FROM_STACK ? qs(job::kFilterInfo) : QString();
}

MeshFilterInterface::FilterClass FilterIsomendPlugin::getClass(QAction *)
{
    /* Filters > Create New Mesh Layer (never Generic: the loader rejects it) */
    return MeshFilterInterface::MeshCreation;
}

MeshFilterInterface::FILTER_ARITY FilterIsomendPlugin::filterArity(QAction *) const
{
    return NONE;
}

int FilterIsomendPlugin::getPreConditions(QAction *) const
{
    return MeshModel::MM_NONE;
}

int FilterIsomendPlugin::postCondition(QAction *) const
{
    return MeshModel::MM_NONE; /* a new layer; the current one is untouched */
}

void FilterIsomendPlugin::initParameterSet(QAction *a, MeshDocument &, RichParameterList &par)
{
    if (ID(a) == FP_ISOSURFACE_FROM_STACK)
        isomend_meshlab::fill_parameters(par);
}

bool FilterIsomendPlugin::fail(const QString &message)
{
    errorMessage = message;
    Log(GLLogStream::WARNING, ("isomend: error: " + message).toStdString());
    return false;
}

bool FilterIsomendPlugin::applyFilter(QAction *a, MeshDocument &md, const RichParameterList &par,
                                      vcg::CallBackPos *cb)
{
    if (ID(a) != FP_ISOSURFACE_FROM_STACK)
        return fail("unknown filter");

    job::Job run;
    const bool ok = run.run(isomend_meshlab::read_parameters(par),
                            [cb](int percent, const char *stage) {
                                return cb ? cb(percent, stage) : true;
                            });
    for (const std::string &line : run.log_lines())
        Log(line);
    if (!run.warning().empty()) /* slices not evenly spaced: meshed where they are */
        Log(GLLogStream::WARNING, "isomend: warning: " + run.warning());
    if (!ok)
        return fail(QString::fromStdString(run.error()));

    if (!run.labels().empty()) { /* a label map: a layer a label */
        if (!isomend_meshlab::add_label_layers(
                md, run, cb, [&md](MeshModel *m) { md.delMesh(m); },
                [this](const std::string &line) { Log(line); }))
            return fail("out of memory while copying the labels into MeshLab");
        if (cb)
            cb(100, "isomend: done");
        return true;
    }
    MeshModel *m = md.addNewMesh("", QString::fromStdString(run.layer_name()), true);
    if (!m)
        return fail("MeshLab could not create a new layer");
    try {
        isomend_meshlab::copy_mesh(run.mesh(), m->cm, cb, run.world_transform());
    } catch (const std::bad_alloc &) {
        md.delMesh(m);
        return fail("out of memory while copying the mesh into MeshLab");
    }
    Log("layer \"%s\": %d vertices, %d faces", qUtf8Printable(m->label()), m->cm.vn, m->cm.fn);
    if (cb)
        cb(100, "isomend: done");
    return true;
}

MESHLAB_PLUGIN_NAME_EXPORTER(FilterIsomendPlugin)
