/*
 * filter_isomend_meshlab.h - the MeshLab code shared by both adapters
 *
 * Parameter list, parameter reading and the mesh copy are written once here
 * and compiled against each MeshLab's own headers: the RichParameter
 * constructors, RichParameterList getters and the vcg allocator are source
 * compatible between MeshLab 2020.09 (filter_isomend.cpp,
 * MeshFilterInterface) and 2021.05+ (filter_isomend_2022.cpp, FilterPlugin).
 * Include it after the MeshLab interface header of the adapter.
 */
#ifndef ISOMEND_FILTER_ISOMEND_MESHLAB_H
#define ISOMEND_FILTER_ISOMEND_MESHLAB_H

#include <cstdint>
#include <functional>
#include <string>
#include <vector>

#include "isomend_filter_job.h"

namespace isomend_meshlab {

inline QString qs(const char *s)
{
    return QString::fromUtf8(s);
}

/* Adds the filter's parameters (names from isomend_filter_job.h) to `par`. */
inline void fill_parameters(RichParameterList &par)
{
    namespace job = isomend_filter;
    const job::Params d = job::default_params();
    auto label = [](const char *name) { return qs(job::param_text(name).label); };
    auto tip = [](const char *name) { return qs(job::param_text(name).tooltip); };

    par.addParam(RichString(job::kParamSource, qs(d.source.c_str()), label(job::kParamSource),
                            tip(job::kParamSource)));
    par.addParam(RichFloat(job::kParamIso, static_cast<float>(d.iso), label(job::kParamIso),
                           tip(job::kParamIso)));
    QStringList methods;
    for (const job::MethodChoice &m : job::method_choices())
        methods << qs(m.display.c_str());
    par.addParam(RichEnum(job::kParamMethod, d.method_index, methods, label(job::kParamMethod),
                          tip(job::kParamMethod)));
    for (int axis = 0; axis < 3; ++axis)
        par.addParam(RichFloat(job::kParamSpacing[axis], static_cast<float>(d.spacing[axis]),
                               label(job::kParamSpacing[axis]), tip(job::kParamSpacing[axis])));
    par.addParam(RichInt(job::kParamChannel, d.channel, label(job::kParamChannel),
                         tip(job::kParamChannel)));
    par.addParam(RichBool(job::kParamPad, d.pad, label(job::kParamPad), tip(job::kParamPad)));
    par.addParam(RichBool(job::kParamFlip, d.flip_normals, label(job::kParamFlip),
                          tip(job::kParamFlip)));
    par.addParam(RichString(job::kParamRawDims, qs(d.raw_dims.c_str()), label(job::kParamRawDims),
                            tip(job::kParamRawDims)));
    QStringList types;
    for (const std::string &t : job::raw_type_choices())
        types << qs(t.c_str());
    par.addParam(RichEnum(job::kParamRawType, d.raw_type_index, types, label(job::kParamRawType),
                          tip(job::kParamRawType)));
    par.addParam(RichString(job::kParamSeries, qs(d.series.c_str()), label(job::kParamSeries),
                            tip(job::kParamSeries)));
    par.addParam(RichBool(job::kParamGridAxes, d.grid_axes, label(job::kParamGridAxes),
                          tip(job::kParamGridAxes)));
    /* post-processing, in the order the job applies them (all off by default) */
    par.addParam(RichInt(job::kParamMinComponent, d.min_component, label(job::kParamMinComponent),
                         tip(job::kParamMinComponent)));
    par.addParam(RichInt(job::kParamSmooth, d.smooth_iterations, label(job::kParamSmooth),
                         tip(job::kParamSmooth)));
    par.addParam(RichFloat(job::kParamDecimate, static_cast<float>(d.decimate_ratio),
                           label(job::kParamDecimate), tip(job::kParamDecimate)));
    /* label maps: one layer a label */
    par.addParam(RichString(job::kParamLabels, qs(d.labels.c_str()), label(job::kParamLabels),
                            tip(job::kParamLabels)));
    par.addParam(RichString(job::kParamLabelTable, qs(d.label_table.c_str()),
                            label(job::kParamLabelTable), tip(job::kParamLabelTable)));
}

/* Reads the values back. */
inline isomend_filter::Params read_parameters(const RichParameterList &par)
{
    namespace job = isomend_filter;
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
    if (par.hasParameter(job::kParamSeries)) /* older .mlx scripts lack them */
        p.series = par.getString(job::kParamSeries).toStdString();
    if (par.hasParameter(job::kParamGridAxes))
        p.grid_axes = par.getBool(job::kParamGridAxes);
    if (par.hasParameter(job::kParamMinComponent))
        p.min_component = par.getInt(job::kParamMinComponent);
    if (par.hasParameter(job::kParamSmooth))
        p.smooth_iterations = par.getInt(job::kParamSmooth);
    if (par.hasParameter(job::kParamDecimate))
        p.decimate_ratio = par.getFloat(job::kParamDecimate);
    if (par.hasParameter(job::kParamLabels))
        p.labels = par.getString(job::kParamLabels).toStdString();
    if (par.hasParameter(job::kParamLabelTable))
        p.label_table = par.getString(job::kParamLabelTable).toStdString();
    return p;
}

/*
 * Copies an isomend mesh (positions, unit normals, triangles) into an empty
 * CMeshO.  The vertex normals stay the core's gradient normals (unit
 * length); UpdateBoxAndNormals() would replace them by unnormalised face
 * averages, so only the box and the face normals are computed.  May throw
 * std::bad_alloc.
 */
inline void copy_mesh(const isomend_mesh *src, CMeshO &cm, vcg::CallBackPos *cb,
                      const double *world = nullptr)
{
    const size_t nv = isomend_mesh_vertex_count(src);
    const size_t nt = isomend_mesh_triangle_count(src);
    const float *pos = isomend_mesh_positions(src);
    const float *nrm = isomend_mesh_normals(src);
    const uint32_t *tri = isomend_mesh_triangles(src);
    /* a DICOM series in patient space: the mesh through its transform */
    std::vector<float> wpos, wnrm;
    std::vector<uint32_t> wtri;
    if (world && nt) {
        wpos.resize(3 * nv);
        wnrm.resize(nrm ? 3 * nv : 0);
        wtri.resize(3 * nt);
        if (isomend_mesh_copy_transformed(src, world, wpos.data(), nrm ? wnrm.data() : nullptr,
                                          wtri.data(), nullptr) == ISOMEND_OK) {
            pos = wpos.data();
            nrm = nrm ? wnrm.data() : nullptr;
            tri = wtri.data();
        }
    }

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
    vcg::tri::UpdateNormal<CMeshO>::PerFaceNormalized(cm);
    if (!nrm)
        vcg::tri::UpdateNormal<CMeshO>::PerVertexNormalized(cm);
}

/*
 * Label-map mode (run.labels() not empty): one new layer a label, named
 * after it, its colour on every vertex and face (MeshLab shows the vertex
 * colour; a PLY export keeps both), and a log line a layer.  Returns false
 * when memory ran out, after removing every layer it had made with
 * `remove` (the two MeshLab APIs delete a layer differently).
 */
inline bool add_label_layers(MeshDocument &md, const isomend_filter::Job &run,
                             vcg::CallBackPos *cb, const std::function<void(MeshModel *)> &remove,
                             const std::function<void(const std::string &)> &log)
{
    std::vector<MeshModel *> made;
    try {
        for (const isomend_filter::LabelLayer &l : run.labels()) {
            MeshModel *m = md.addNewMesh("", QString::fromStdString(l.name), true);
            if (!m)
                throw std::bad_alloc();
            made.push_back(m);
            copy_mesh(l.mesh, m->cm, cb, run.world_transform());
            m->updateDataMask(MeshModel::MM_VERTCOLOR | MeshModel::MM_FACECOLOR);
            const vcg::Color4b c(l.rgb[0], l.rgb[1], l.rgb[2], 255);
            for (auto &v : m->cm.vert)
                v.C() = c;
            for (auto &f : m->cm.face)
                f.C() = c;
        }
    } catch (const std::bad_alloc &) {
        for (MeshModel *m : made)
            remove(m);
        return false;
    }
    for (MeshModel *m : made)
        log("layer \"" + m->label().toStdString() + "\": " + std::to_string(m->cm.vn) +
            " vertices, " + std::to_string(m->cm.fn) + " faces");
    return true;
}

} // namespace isomend_meshlab

#endif /* ISOMEND_FILTER_ISOMEND_MESHLAB_H */
