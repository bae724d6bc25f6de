// nifti.cpp - NIfTI-1, NIfTI-2 and ANALYZE 7.5 volumes with libnifti2.
//
// isomend_io.h ("NIfTI") is the contract; docs/nifti.md says why.  The passes:
//   1. detection (api.cpp asks is_nifti_path): .nii and .nii.gz by name;
//      .hdr/.img (also .gz) when libnifti finds a NIfTI or ANALYZE header
//      (a Radiance .hdr image is left to the image reader);
//   2. header: nifti_image_read(path, 0) (no data), then our own checks,
//      each naming the file: 3D (a 4th..7th dimension of 1 is fine, more is
//      refused), every dimension >= 2, a datatype isomend meshes, the data
//      file present and long enough (uncompressed: checked at open; gzip:
//      at read, when libnifti's read comes up short);
//   3. type: the stored type, or with scl_slope/scl_inter (slope != 0 and
//      not exactly 1, 0) the type that holds every scaled value, by the
//      DICOM rule: integer slope and intercept on integer samples give the
//      smallest of u8, i16, u16, i32 (else f64) that holds the scaled
//      stored range, anything else f32 (f64 for 32-bit and f64 samples);
//   4. geometry: the sform if sform_code > 0, else the qform if
//      qform_code > 0, else pixdim scaling ("method 1"), in millimetres
//      (xyz_units metres and microns converted).  The volume is delivered in
//      the grid's own frame: x = i, y = j, z = k, spacing = |pixdim|
//      (positive), origin L^-1 t, and isomend_io_world_transform() gives
//      [L | t - L origin] with L = F A diag(1/spacing), t = F A_t; F =
//      diag(-1, -1, 1) turns NIfTI's RAS into the patient LPS of DICOM (the
//      default), the identity keeps RAS (ISOMEND_IO_AXES_RAS).  det L < 0 is
//      a mirror, which isomend_mesh_copy_transformed() handles (winding
//      reversed);
//   5. reading: our own (zlib's gz* functions, byte order swapped with
//      libnifti's nifti_swap_Nbytes), slice by slice for uncompressed files
//      (progress and cancellation between slices), the whole file in one
//      pass for gzip (a slice of a gzip stream costs decompressing
//      everything before it), then conversion/scaling.  libnifti's own data
//      reader prints on stderr and frees the caller's buffer on a short gzip
//      stream, so it reads headers only; its debug level is set to 0 once
//      per process (like GDCM's trace), and our checks give the messages.
#include "nifti.hpp"

#include <algorithm>
#include <cerrno>
#include <cmath>
#include <cstring>
#include <mutex>
#include <sys/stat.h>
#include <vector>

#include <nifti2_io.h>
#include <zlib.h>

namespace isomend_io {

namespace {

void quiet_nifti() {
    static std::once_flag once;
    std::call_once(once, [] { nifti_set_debug_level(0); });
}

nifti_image *nim_of(const NiftiVolume &v) { return (nifti_image *)v.nim.get(); }

bool ends_with(const std::string &s, const char *suffix) {
    size_t n = std::strlen(suffix);
    if (s.size() < n) return false;
    for (size_t i = 0; i < n; i++)
        if (std::tolower((unsigned char)s[s.size() - n + i]) != suffix[i]) return false;
    return true;
}

bool exists(const std::string &p, uint64_t *size = nullptr) {
    struct stat st;
    if (::stat(p.c_str(), &st) != 0 || !S_ISREG(st.st_mode)) return false;
    if (size) *size = (uint64_t)st.st_size;
    return true;
}

// The header's first field, sizeof_hdr (348 for NIfTI-1 and ANALYZE, 540
// for NIfTI-2, in either byte order), read through zlib (which reads
// uncompressed files as they are); 0 if unreadable.  libnifti 3.0.1's
// is_nifti_file() does not know NIfTI-2, so the check is our own.
int header_size(const std::string &path) {
    gzFile f = gzopen(path.c_str(), "rb");
    if (!f) return 0;
    unsigned char b[4] = {0, 0, 0, 0};
    int n = gzread(f, b, 4);
    gzclose(f);
    if (n != 4) return 0;
    uint32_t le = b[0] | (uint32_t)b[1] << 8 | (uint32_t)b[2] << 16 | (uint32_t)b[3] << 24;
    uint32_t be = b[3] | (uint32_t)b[2] << 8 | (uint32_t)b[1] << 16 | (uint32_t)b[0] << 24;
    for (uint32_t v : {le, be})
        if (v == 348 || v == 540) return (int)v;
    return 0;
}

std::string take(char *p) { // a string libnifti malloc'ed
    std::string s = p ? p : "";
    std::free(p);
    return s;
}

bool is_integer(double v) { return std::isfinite(v) && v == std::floor(v) && std::fabs(v) < 9e15; }

isomend_type integer_type_for(double lo, double hi) {
    if (lo >= 0 && hi <= 255) return ISOMEND_U8;
    if (lo >= -32768 && hi <= 32767) return ISOMEND_I16;
    if (lo >= 0 && hi <= 65535) return ISOMEND_U16;
    if (lo >= INT32_MIN && hi <= INT32_MAX) return ISOMEND_I32;
    return ISOMEND_F64;
}

// stored DT_* -> what libnifti hands us; false for what isomend does not mesh
bool stored_type(int dt, isomend_type &t, double &lo, double &hi) {
    switch (dt) {
    case DT_UINT8: t = ISOMEND_U8; lo = 0; hi = 255; return true;
    case DT_INT8: t = ISOMEND_I8; lo = -128; hi = 127; return true;
    case DT_UINT16: t = ISOMEND_U16; lo = 0; hi = 65535; return true;
    case DT_INT16: t = ISOMEND_I16; lo = -32768; hi = 32767; return true;
    case DT_INT32: t = ISOMEND_I32; lo = INT32_MIN; hi = INT32_MAX; return true;
    case DT_UINT32: t = ISOMEND_I32; lo = 0; hi = 4294967295.0; return true; // read as 4 bytes, see convert
    case DT_FLOAT32: t = ISOMEND_F32; lo = hi = 0; return true;
    case DT_FLOAT64: t = ISOMEND_F64; lo = hi = 0; return true;
    default: return false;
    }
}

double det3(const double *m) {
    return m[0] * (m[4] * m[8] - m[5] * m[7]) - m[1] * (m[3] * m[8] - m[5] * m[6]) +
           m[2] * (m[3] * m[7] - m[4] * m[6]);
}

void inverse3(const double *m, double *r) {
    double d = det3(m);
    r[0] = (m[4] * m[8] - m[5] * m[7]) / d;
    r[1] = (m[2] * m[7] - m[1] * m[8]) / d;
    r[2] = (m[1] * m[5] - m[2] * m[4]) / d;
    r[3] = (m[5] * m[6] - m[3] * m[8]) / d;
    r[4] = (m[0] * m[8] - m[2] * m[6]) / d;
    r[5] = (m[2] * m[3] - m[0] * m[5]) / d;
    r[6] = (m[3] * m[7] - m[4] * m[6]) / d;
    r[7] = (m[1] * m[6] - m[0] * m[7]) / d;
    r[8] = (m[0] * m[4] - m[1] * m[3]) / d;
}

template <typename In, typename Out> void scale_to(const In *src, size_t n, const NiftiVolume &v, Out *dst) {
    if (!v.scaled) {
        for (size_t i = 0; i < n; i++) dst[i] = (Out)src[i];
    } else if (v.integer_scale && v.type != ISOMEND_F32 && v.type != ISOMEND_F64) {
        const int64_t s = (int64_t)v.slope, c = (int64_t)v.inter;
        for (size_t i = 0; i < n; i++) dst[i] = (Out)((int64_t)src[i] * s + c);
    } else {
        for (size_t i = 0; i < n; i++) dst[i] = (Out)((double)src[i] * v.slope + v.inter);
    }
}

template <typename In> void convert_from(const In *src, size_t n, const NiftiVolume &v, void *dst) {
    switch (v.type) {
    case ISOMEND_U8: scale_to(src, n, v, (uint8_t *)dst); break;
    case ISOMEND_I8: scale_to(src, n, v, (int8_t *)dst); break;
    case ISOMEND_U16: scale_to(src, n, v, (uint16_t *)dst); break;
    case ISOMEND_I16: scale_to(src, n, v, (int16_t *)dst); break;
    case ISOMEND_I32: scale_to(src, n, v, (int32_t *)dst); break;
    case ISOMEND_F32: scale_to(src, n, v, (float *)dst); break;
    case ISOMEND_F64: scale_to(src, n, v, (double *)dst); break;
    }
}

// n stored samples (as libnifti returns them, machine order) -> delivered
void convert(const NiftiVolume &v, const void *src, size_t n, void *dst) {
    switch (v.datatype) {
    case DT_UINT8: convert_from((const uint8_t *)src, n, v, dst); break;
    case DT_INT8: convert_from((const int8_t *)src, n, v, dst); break;
    case DT_UINT16: convert_from((const uint16_t *)src, n, v, dst); break;
    case DT_INT16: convert_from((const int16_t *)src, n, v, dst); break;
    case DT_INT32: convert_from((const int32_t *)src, n, v, dst); break;
    case DT_UINT32: convert_from((const uint32_t *)src, n, v, dst); break;
    case DT_FLOAT32: convert_from((const float *)src, n, v, dst); break;
    case DT_FLOAT64: convert_from((const double *)src, n, v, dst); break;
    default: throw IoError(ISOMEND_IO_ERR_INTERNAL, v.path + ": unexpected datatype");
    }
}

bool converts(const NiftiVolume &v) {
    return v.scaled || v.datatype == DT_UINT32; // else the stored bytes are the delivered ones
}

size_t stored_size(const NiftiVolume &v);

// Reads stored slice k (k < 0: the whole volume) into `dst`, `bytes` of
// them, and swaps them to the machine's byte order.  Our own reader (zlib's
// gz* functions, which read uncompressed files as they are): libnifti's
// nifti_read_collapsed_image() prints on stderr whatever the debug level and
// frees the caller's buffer when a gzip stream ends early.
void read_stored(const NiftiVolume &v, int64_t k, void *dst, size_t bytes) {
    const nifti_image *nim = nim_of(v);
    const uint64_t slice = (uint64_t)v.dims[0] * (uint64_t)v.dims[1] * stored_size(v);
    const uint64_t offset = (uint64_t)nim->iname_offset + (k < 0 ? 0 : (uint64_t)k * slice);
    std::string what = k < 0 ? std::string("the volume") : "slice " + std::to_string(k);
    gzFile f = gzopen(v.image_path.c_str(), "rb");
    if (!f) throw IoError(ISOMEND_IO_ERR_UNREADABLE, v.image_path + ": cannot open: " + std::strerror(errno));
    gzbuffer(f, 1 << 18);
    bool ok = gzseek64(f, (z_off64_t)offset, SEEK_SET) == (z_off64_t)offset;
    size_t done = 0;
    while (ok && done < bytes) {
        unsigned chunk = (unsigned)std::min<size_t>(bytes - done, size_t(1) << 30);
        int n = gzread(f, (char *)dst + done, chunk);
        if (n <= 0) break;
        done += (size_t)n;
    }
    int zerr = 0;
    const char *zmsg = gzerror(f, &zerr);
    std::string reason = zerr != Z_OK && zerr != Z_BUF_ERROR && zmsg ? std::string(": ") + zmsg : "";
    gzclose(f);
    if (!ok || done != bytes)
        throw IoError(ISOMEND_IO_ERR_CORRUPT,
                      v.image_path + ": truncated or corrupt data: " + what + " needs " + std::to_string(bytes) +
                          " bytes from offset " + std::to_string(offset) + (v.gzip ? " of the gzip stream" : "") +
                          ", " + std::to_string(done) + " could be read" + reason);
    if (nim->nbyper > 1 && nim->byteorder != nifti_short_order())
        nifti_swap_Nbytes((int64_t)(bytes / (size_t)nim->nbyper), nim->nbyper, dst);
}

size_t stored_size(const NiftiVolume &v) { return (size_t)nim_of(v)->nbyper; }

} // namespace

void NiftiImageDeleter::operator()(void *nim) const { nifti_image_free((nifti_image *)nim); }

size_t NiftiVolume::sample_size() const { return isomend_type_size(type); }

bool is_nifti_path(const std::string &path) {
    if (ends_with(path, ".nii") || ends_with(path, ".nii.gz")) return true;
    if (!(ends_with(path, ".hdr") || ends_with(path, ".img") || ends_with(path, ".hdr.gz") ||
          ends_with(path, ".img.gz")))
        return false;
    quiet_nifti();
    std::string hdr = take(nifti_findhdrname(path.c_str()));
    return !hdr.empty() && header_size(hdr) != 0;
}

void nifti_open(const std::string &path, int axes, NiftiVolume &v) {
    quiet_nifti();
    v = NiftiVolume{};
    v.path = path;
    v.axes = axes;
    if (!exists(path)) throw IoError(ISOMEND_IO_ERR_NOT_FOUND, path + ": file not found");
    v.header_path = take(nifti_findhdrname(path.c_str()));
    if (v.header_path.empty())
        throw IoError(ISOMEND_IO_ERR_NOT_FOUND, path + ": the header (.hdr) of this .img file is missing");
    uint64_t hsize = 0;
    exists(v.header_path, &hsize);
    if (!header_size(v.header_path))
        throw IoError(ISOMEND_IO_ERR_UNREADABLE,
                      v.header_path + ": not a NIfTI-1, NIfTI-2 or ANALYZE 7.5 header (" + std::to_string(hsize) +
                          " bytes; a NIfTI header starts with its size, 348 or 540)");
    v.nim.reset(nifti_image_read(v.header_path.c_str(), 0));
    nifti_image *nim = nim_of(v);
    if (!nim)
        throw IoError(ISOMEND_IO_ERR_CORRUPT, v.header_path +
                                                  ": libnifti cannot read this header (truncated, or "
                                                  "inconsistent dimensions, datatype or offset)");
    // libnifti 3.0.1 sets nifti_type 1/2 for NIfTI-2 too: the header size tells
    v.version = nim->nifti_type == NIFTI_FTYPE_ANALYZE ? 0 : header_size(v.header_path) == 540 ? 2 : 1;
    v.image_path = nim->iname ? nim->iname : v.header_path;
    v.two_files = v.image_path != v.header_path;
    v.gzip = ends_with(v.image_path, ".gz");

    // dimensions: 3D, extra dimensions of 1 allowed
    const int64_t *d = nim->dim;
    if (nim->nt > 1 || nim->nu > 1 || nim->nv > 1 || nim->nw > 1) {
        std::string dims;
        for (int64_t a = 1; a <= d[0] && a <= 7; a++) dims += (a > 1 ? "x" : "") + std::to_string(d[a]);
        throw IoError(ISOMEND_IO_ERR_UNSUPPORTED,
                      path + ": a " + std::to_string(d[0]) + "D image (" + dims + ", " +
                          std::to_string(nim->nt * std::max<int64_t>(nim->nu, 1) * std::max<int64_t>(nim->nv, 1) *
                                         std::max<int64_t>(nim->nw, 1)) +
                          " volumes); isomend meshes one 3D volume: extract one first (e.g. fslroi, or "
                          "nibabel's img.slicer[..., 0])");
    }
    v.dims[0] = nim->nx;
    v.dims[1] = nim->ny;
    v.dims[2] = nim->nz;
    if (v.dims[0] < 2 || v.dims[1] < 2 || v.dims[2] < 2)
        throw IoError(ISOMEND_IO_ERR_TOO_FEW_SLICES,
                      path + ": dimensions " + std::to_string(v.dims[0]) + "x" + std::to_string(v.dims[1]) + "x" +
                          std::to_string(v.dims[2]) + "; every dimension must be at least 2");

    // datatype and scaling
    v.datatype = nim->datatype;
    const char *dn = nifti_datatype_to_string(nim->datatype);
    v.datatype_name = dn ? dn : ("datatype " + std::to_string(nim->datatype));
    double lo = 0, hi = 0;
    if (!stored_type(nim->datatype, v.stored, lo, hi))
        throw IoError(ISOMEND_IO_ERR_UNSUPPORTED,
                      path + ": datatype " + v.datatype_name +
                          " is not a scalar isomend meshes (uint8, int8, uint16, int16, int32, uint32, "
                          "float32, float64; colour and complex images are refused)");
    v.slope = nim->scl_slope;
    v.inter = nim->scl_inter;
    v.scaled = std::isfinite(v.slope) && v.slope != 0 && std::isfinite(v.inter) && !(v.slope == 1 && v.inter == 0);
    v.integer_scale = is_integer(v.slope) && is_integer(v.inter);
    const bool integer_samples = v.datatype != DT_FLOAT32 && v.datatype != DT_FLOAT64;
    const bool wide = v.datatype == DT_INT32 || v.datatype == DT_UINT32 || v.datatype == DT_FLOAT64;
    if (!v.scaled) {
        v.type = v.datatype == DT_UINT32 ? ISOMEND_F64 : v.stored;
    } else if (v.integer_scale && integer_samples) {
        double a = v.slope * lo + v.inter, b = v.slope * hi + v.inter;
        v.type = integer_type_for(std::min(a, b), std::max(a, b));
    } else {
        v.type = wide ? ISOMEND_F64 : ISOMEND_F32;
    }

    // the data are there (uncompressed: now; gzip: when read)
    const uint64_t need = (uint64_t)stored_size(v) * (uint64_t)v.dims[0] * (uint64_t)v.dims[1] * (uint64_t)v.dims[2];
    uint64_t isize = 0;
    if (!exists(v.image_path, &isize))
        throw IoError(ISOMEND_IO_ERR_NOT_FOUND, path + ": its image data file " + v.image_path + " is missing");
    if (!v.gzip && isize < (uint64_t)nim->iname_offset + need)
        throw IoError(ISOMEND_IO_ERR_CORRUPT,
                      v.image_path + ": truncated: the data need " + std::to_string(need) + " bytes from offset " +
                          std::to_string(nim->iname_offset) + ", the file has " +
                          std::to_string(isize > (uint64_t)nim->iname_offset ? isize - (uint64_t)nim->iname_offset : 0) +
                          " after it");

    // geometry: sform, else qform, else pixdim (method 1), in mm
    v.sform_code = nim->sform_code;
    v.qform_code = nim->qform_code;
    const nifti_dmat44 *m = &nim->qto_xyz; // libnifti: pixdim scaling when qform_code is 0
    v.transform = v.qform_code > 0 ? "qform" : "pixdim";
    if (v.sform_code > 0) {
        m = &nim->sto_xyz;
        v.transform = "sform";
    }
    switch (nim->xyz_units) {
    case NIFTI_UNITS_METER: v.units_to_mm = 1000; break;
    case NIFTI_UNITS_MICRON: v.units_to_mm = 0.001; break;
    default: v.units_to_mm = 1; break;
    }
    for (int r = 0; r < 3; r++)
        for (int c = 0; c < 4; c++) {
            double x = m->m[r][c];
            // method 1 (ANALYZE): diag(|pixdim|), no translation (what
            // libnifti's qto_xyz holds then, written out to not hang on it)
            if (v.transform == "pixdim") x = c == r ? std::fabs(nim->pixdim[r + 1]) : 0.0;
            v.file_affine[4 * r + c] = x * v.units_to_mm;
        }
    for (int a = 0; a < 12; a++)
        if (!std::isfinite(v.file_affine[a]))
            throw IoError(ISOMEND_IO_ERR_CORRUPT, path + ": the " + v.transform + " is not finite");
    for (int a = 0; a < 3; a++) {
        double p = std::fabs(nim->pixdim[a + 1]) * v.units_to_mm;
        if (!(std::isfinite(p) && p > 0)) { // no pixdim: the affine's column length
            const double *A = v.file_affine;
            p = std::sqrt(A[a] * A[a] + A[4 + a] * A[4 + a] + A[8 + a] * A[8 + a]);
        }
        v.spacing[a] = std::isfinite(p) && p > 0 ? p : 1.0;
    }
    const double F[3] = {axes == ISOMEND_IO_AXES_RAS ? 1.0 : -1.0, axes == ISOMEND_IO_AXES_RAS ? 1.0 : -1.0, 1.0};
    for (int r = 0; r < 3; r++)
        for (int c = 0; c < 3; c++) v.linear[3 * r + c] = F[r] * v.file_affine[4 * r + c] / v.spacing[c];
    double det = det3(v.linear);
    if (!std::isfinite(det) || std::fabs(det) < 1e-12)
        throw IoError(ISOMEND_IO_ERR_CORRUPT, path + ": the " + v.transform +
                                                  " is singular (it maps the grid onto a plane or a line)");
    double t[3];
    for (int r = 0; r < 3; r++) t[r] = F[r] * v.file_affine[4 * r + 3];
    nifti_place(v, t, true);
}

void nifti_place(NiftiVolume &v, const double world_origin[3], bool given) {
    if (given)
        for (int a = 0; a < 3; a++) v.world_origin[a] = world_origin[a];
    double inv[9];
    inverse3(v.linear, inv);
    for (int r = 0; r < 3; r++)
        v.origin[r] = inv[3 * r] * v.world_origin[0] + inv[3 * r + 1] * v.world_origin[1] +
                      inv[3 * r + 2] * v.world_origin[2];
    bool id = v.axes == ISOMEND_IO_AXES_GRID;
    for (int r = 0; r < 3 && !id; r++) {
        for (int c = 0; c < 3; c++) v.affine[4 * r + c] = v.linear[3 * r + c];
        v.affine[4 * r + 3] = v.world_origin[r] - (v.linear[3 * r] * v.origin[0] + v.linear[3 * r + 1] * v.origin[1] +
                                                   v.linear[3 * r + 2] * v.origin[2]);
    }
    if (!id) {
        id = true;
        for (int i = 0; i < 12; i++)
            if (v.affine[i] != (i % 5 == 0 ? 1.0 : 0.0)) id = false;
    }
    v.identity = id;
    if (id)
        for (int i = 0; i < 12; i++) v.affine[i] = i % 5 == 0 ? 1.0 : 0.0;
}

void nifti_read_slice(const NiftiVolume &v, int64_t k, void *out) {
    const size_t n = (size_t)v.dims[0] * (size_t)v.dims[1];
    const size_t bytes = n * stored_size(v);
    if (!converts(v)) {
        read_stored(v, k, out, bytes);
        return;
    }
    std::vector<unsigned char> tmp(bytes);
    read_stored(v, k, tmp.data(), bytes);
    convert(v, tmp.data(), n, out);
}

void nifti_read(const NiftiVolume &v, void *buffer, const std::function<bool(double)> &progress) {
    const int64_t nz = v.dims[2];
    const size_t n = (size_t)v.dims[0] * (size_t)v.dims[1];
    const size_t sb = v.slice_bytes();
    if (progress && progress(0.0)) throw IoError(ISOMEND_IO_ERR_CANCELLED, "cancelled while reading " + v.path);
    if (v.gzip) {
        const size_t bytes = n * (size_t)nz * stored_size(v);
        if (!converts(v)) {
            read_stored(v, -1, buffer, bytes);
        } else {
            std::vector<unsigned char> tmp(bytes);
            read_stored(v, -1, tmp.data(), bytes);
            convert(v, tmp.data(), n * (size_t)nz, buffer);
        }
    } else {
        for (int64_t k = 0; k < nz; k++) {
            nifti_read_slice(v, k, (char *)buffer + (size_t)k * sb);
            if (progress && progress((double)(k + 1) / (double)nz))
                throw IoError(ISOMEND_IO_ERR_CANCELLED, "cancelled while reading " + v.path);
        }
    }
    if (progress) progress(1.0);
}

} // namespace isomend_io
