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

#include <cstdint>
#include <new>
#include <string>
#include <vector>

#include "isomend_filter_job.h"

namespace job = isomend_filter;

namespace {

QString qs(const char *s)
{
    return QString::fromUtf8(s);
}


/* Copies an isomend mesh (positions, unit normals, triangles) into cm. */
void copy_mesh(const isomend_mesh *src, CMeshO &cm, vcg::CallBackPos *cb)
{
    const size_t nv = isomend_mesh_vertex_count(src);
    const size_t nt = isomend_mesh_triangle_count(src);
    const float *pos = isomend_mesh_positions(src);
    const float *nrm = isomend_mesh_normals(src);
    const uint32_t *tri = isomend_mesh_triangles(src);

    auto vi = vcg::tri::Allocator<CMeshO>::AddVertices(cm, nv);
    for (size_t i = 0; i < nv; ++i, ++vi) {
        vi->P() = Point3m(pos[3 * i], pos[3 * i + 1], pos[3 * i + 2]);
        if (nrm)
            vi->N() = Point3m(nrm[3 * i], nrm[3 * i + 1], nrm[3 * i + 2]);
    }
    if (cb)
        cb(97, "isomend: building the layer");
    auto fi = vcg::tri::Allocator<CMeshO>::AddFaces(cm, nt);
    for (size_t t = 0; t < nt; ++t, ++fi)
        for (int c = 0; c < 3; ++c)
            fi->V(c) = &cm.vert[tri[3 * t + c]];
    vcg::tri::UpdateBounding<CMeshO>::Box(cm);
    /* Face normals for flat shading; the vertex normals stay the core's
     * gradient normals (unit length), which UpdateBoxAndNormals() would
     * replace by unnormalised face averages. */
    vcg::tri::UpdateNormal<CMeshO>::PerFaceNormalized(cm);
    if (!nrm)
        vcg::tri::UpdateNormal<CMeshO>::PerVertexNormalized(cm);
}

} // namespace

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
    switch (filter) {
    case FP_ISOSURFACE_FROM_STACK: return qs(job::kFilterName);
    }
    return QString();
}

QString FilterIsomendPlugin::filterInfo(FilterIDType filter) const
{
    switch (filter) {
    case FP_ISOSURFACE_FROM_STACK: return qs(job::kFilterInfo);
    }
    return QString();
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
    if (ID(a) != FP_ISOSURFACE_FROM_STACK)
        return;
    const job::Params d = job::default_params();
    auto text = [](const char *name, const char **label, const char **tip) {
        const job::ParamText t = job::param_text(name);
        *label = t.label;
        *tip = t.tooltip;
    };
    const char *label = nullptr, *tip = nullptr;

    text(job::kParamSource, &label, &tip);
    par.addParam(RichString(job::kParamSource, qs(d.source.c_str()), label, tip));
    text(job::kParamIso, &label, &tip);
    par.addParam(RichFloat(job::kParamIso, static_cast<float>(d.iso), label, tip));

    QStringList methods;
    for (const job::MethodChoice &m : job::method_choices())
        methods << qs(m.display.c_str());
    text(job::kParamMethod, &label, &tip);
    par.addParam(RichEnum(job::kParamMethod, d.method_index, methods, label, tip));

    for (int axis = 0; axis < 3; ++axis) {
        text(job::kParamSpacing[axis], &label, &tip);
        par.addParam(RichFloat(job::kParamSpacing[axis], static_cast<float>(d.spacing[axis]),
                               label, tip));
    }
    text(job::kParamChannel, &label, &tip);
    par.addParam(RichInt(job::kParamChannel, d.channel, label, tip));
    text(job::kParamPad, &label, &tip);
    par.addParam(RichBool(job::kParamPad, d.pad, label, tip));
    text(job::kParamFlip, &label, &tip);
    par.addParam(RichBool(job::kParamFlip, d.flip_normals, label, tip));
    text(job::kParamRawDims, &label, &tip);
    par.addParam(RichString(job::kParamRawDims, qs(d.raw_dims.c_str()), label, tip));

    QStringList types;
    for (const std::string &t : job::raw_type_choices())
        types << qs(t.c_str());
    text(job::kParamRawType, &label, &tip);
    par.addParam(RichEnum(job::kParamRawType, d.raw_type_index, types, label, tip));
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

    job::Params p;
    p.source = par.getString(job::kParamSource).toStdString();
    p.iso = par.getFloat(job::kParamIso);
    p.method_index = par.getEnum(job::kParamMethod);
    for (int axis = 0; axis < 3; ++axis)
        p.spacing[axis] = par.getFloat(job::kParamSpacing[axis]);
    p.channel = par.getInt(job::kParamChannel);
    p.pad = par.getBool(job::kParamPad);
    p.flip_normals = par.getBool(job::kParamFlip);
    p.raw_dims = par.getString(job::kParamRawDims).toStdString();
    p.raw_type_index = par.getEnum(job::kParamRawType);

    job::Job run;
    const bool ok = run.run(p, [cb](int percent, const char *stage) {
        return cb ? cb(percent, stage) : true;
    });
    for (const std::string &line : run.log_lines())
        Log(line);
    if (!ok)
        return fail(QString::fromStdString(run.error()));

    MeshModel *m = md.addNewMesh("", QString::fromStdString(run.layer_name()), true);
    if (!m)
        return fail("MeshLab could not create a new layer");
    try {
        copy_mesh(run.mesh(), m->cm, cb);
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
