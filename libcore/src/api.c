/*
 * api.c - small public helpers: status strings, voxel types, method names,
 * option defaults, and the mesh's accessors.
 */
#include "isomend.h"

#include "mesh_internal.h"
#include "methods.h"

#include <stdlib.h>
#include <string.h>

const char *isomend_status_string(isomend_status status)
{
    switch (status) {
    case ISOMEND_OK: return "success";
    case ISOMEND_ERR_INVALID_ARGUMENT: return "invalid argument";
    case ISOMEND_ERR_BAD_DIMENSIONS: return "bad volume dimensions (each must be at least 2, or 1 with padding)";
    case ISOMEND_ERR_BAD_SPACING: return "bad spacing (each must be finite and > 0)";
    case ISOMEND_ERR_BAD_ISO: return "bad iso level (must be finite)";
    case ISOMEND_ERR_OUT_OF_MEMORY: return "out of memory";
    case ISOMEND_ERR_TOO_LARGE: return "mesh too large (more than 2^32-1 vertices)";
    case ISOMEND_ERR_CANCELLED: return "cancelled";
    case ISOMEND_ERR_THREAD: return "could not start a worker thread";
    case ISOMEND_ERR_UNSUPPORTED: return "method not available in this build";
    case ISOMEND_ERR_SINK: return "the mesh sink stopped the extraction";
    case ISOMEND_ERR_SLICE_COUNT: return "wrong number of slices for the volume's dimensions";
    }
    return "unknown status";
}

const char *isomend_version(void) { return ISOMEND_VERSION_STRING; }

static const struct {
    const char *name;
    size_t size;
} type_info[ISOMEND_TYPE_COUNT] = {
    {"u8", 1}, {"i8", 1}, {"u16", 2}, {"i16", 2}, {"i32", 4}, {"f32", 4}, {"f64", 8},
};

size_t isomend_type_size(isomend_type type)
{
    return (unsigned)type < ISOMEND_TYPE_COUNT ? type_info[type].size : 0;
}

const char *isomend_type_name(isomend_type type)
{
    return (unsigned)type < ISOMEND_TYPE_COUNT ? type_info[type].name : NULL;
}

isomend_status isomend_type_from_name(const char *name, isomend_type *type)
{
    if (!name || !type)
        return ISOMEND_ERR_INVALID_ARGUMENT;
    for (int t = 0; t < ISOMEND_TYPE_COUNT; t++)
        if (strcmp(name, type_info[t].name) == 0) {
            *type = (isomend_type)t;
            return ISOMEND_OK;
        }
    return ISOMEND_ERR_INVALID_ARGUMENT;
}

static const char *const method_names[ISOMEND_METHOD_COUNT] = {
    "mc", "durst", "dmc", "facial", "gradient", "asymptotic", "tetra", "mc33",
};

const char *isomend_method_name(isomend_method method)
{
    return (unsigned)method < ISOMEND_METHOD_COUNT ? method_names[method] : NULL;
}

isomend_status isomend_method_from_name(const char *name, isomend_method *method)
{
    if (!name || !method)
        return ISOMEND_ERR_INVALID_ARGUMENT;
    for (int m = 0; m < ISOMEND_METHOD_COUNT; m++)
        if (strcmp(name, method_names[m]) == 0) {
            *method = (isomend_method)m;
            return ISOMEND_OK;
        }
    return ISOMEND_ERR_INVALID_ARGUMENT;
}

int isomend_method_available(isomend_method method)
{
    return method == ISOMEND_METHOD_MC || method == ISOMEND_METHOD_DURST ||
           method == ISOMEND_METHOD_DMC || methods_handles(method);
}

void isomend_options_init(isomend_options *opts)
{
    if (!opts)
        return;
    memset(opts, 0, sizeof(*opts));
    opts->iso = 0.0;
    opts->method = ISOMEND_METHOD_DMC;
    opts->flags = 0;
    opts->threads = 0;
}

void isomend_volume_init(isomend_volume *vol, const void *data, isomend_type type, int64_t nx,
                         int64_t ny, int64_t nz)
{
    if (!vol)
        return;
    memset(vol, 0, sizeof(*vol));
    vol->data = data;
    vol->type = type;
    vol->dims[0] = nx;
    vol->dims[1] = ny;
    vol->dims[2] = nz;
    for (int a = 0; a < 3; a++)
        vol->spacing[a] = 1.0;
}

/* ------------------------------------------------------------------- mesh */

void isomend_mesh_destroy(isomend_mesh *mesh)
{
    if (!mesh)
        return;
    release_output(mesh->pos, mesh->mapped[0]);
    release_output(mesh->nrm, mesh->mapped[1]);
    release_output(mesh->tri, mesh->mapped[2]);
    release_output(mesh->org, mesh->mapped[3]);
    free(mesh->slice_store);
    free(mesh);
}

size_t isomend_mesh_vertex_count(const isomend_mesh *mesh) { return mesh ? mesh->nv : 0; }
size_t isomend_mesh_triangle_count(const isomend_mesh *mesh) { return mesh ? mesh->nt : 0; }
const float *isomend_mesh_positions(const isomend_mesh *mesh) { return mesh ? mesh->pos : NULL; }
const float *isomend_mesh_normals(const isomend_mesh *mesh) { return mesh ? mesh->nrm : NULL; }
const uint32_t *isomend_mesh_triangles(const isomend_mesh *mesh) { return mesh ? mesh->tri : NULL; }
const uint8_t *isomend_mesh_triangle_origins(const isomend_mesh *mesh)
{
    return mesh ? mesh->org : NULL;
}

void isomend_mesh_grid_box(const isomend_mesh *mesh, double box[6])
{
    if (!mesh || !box)
        return;
    memcpy(box, mesh->box, sizeof(mesh->box));
}

isomend_status isomend_mesh_copy(const isomend_mesh *mesh, float *positions, float *normals,
                                 uint32_t *triangles, uint8_t *origins)
{
    if (!mesh)
        return ISOMEND_ERR_INVALID_ARGUMENT;
    if ((normals && !mesh->nrm) || (origins && !mesh->org))
        return ISOMEND_ERR_INVALID_ARGUMENT;
    if (positions)
        memcpy(positions, mesh->pos, sizeof(float) * 3 * mesh->nv);
    if (normals)
        memcpy(normals, mesh->nrm, sizeof(float) * 3 * mesh->nv);
    if (triangles)
        memcpy(triangles, mesh->tri, sizeof(uint32_t) * 3 * mesh->nt);
    if (origins)
        memcpy(origins, mesh->org, mesh->nt);
    return ISOMEND_OK;
}
