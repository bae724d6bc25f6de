// nifti.hpp - the NIfTI reader's private interface (nifti.cpp, libnifti2).
//
// Like the DICOM reader, kept apart from the image backends: nothing here
// includes OpenImageIO, so both builds of libisomend_io read NIfTI alike.
// api.cpp decides whether a path is NIfTI (is_nifti_path), calls
// nifti_open() and routes reads here.
#ifndef ISOMEND_IO_NIFTI_HPP
#define ISOMEND_IO_NIFTI_HPP

#include <cstdint>
#include <functional>
#include <memory>
#include <string>

#include "internal.hpp"
#include "isomend_io.h"

namespace isomend_io {

// True for a path named .nii / .nii.gz, or a .hdr / .img (optionally .gz)
// whose header is a NIfTI-1, NIfTI-2 or ANALYZE 7.5 header (a Radiance
// .hdr image is not: it goes to the image reader).
bool is_nifti_path(const std::string &path);

struct NiftiImageDeleter {
    void operator()(void *nim) const;
};

// An opened NIfTI file (header read, no voxel data).
struct NiftiVolume {
    std::string path;          // as given (messages)
    std::string header_path, image_path;
    std::unique_ptr<void, NiftiImageDeleter> nim; // nifti_image*, header only
    int version = 1;           // 1, 2, or 0 for ANALYZE 7.5
    bool two_files = false;    // .hdr/.img pair
    bool gzip = false;         // the image data are gzip-compressed
    int64_t dims[3] = {0, 0, 0};
    int datatype = 0;          // NIfTI DT_* code as stored
    std::string datatype_name; // "INT16", ...
    isomend_type stored = ISOMEND_U8; // stored samples as read (u32: delivered via f64)
    isomend_type type = ISOMEND_U8;   // delivered type
    bool scaled = false;       // scl_slope/scl_inter applied
    bool integer_scale = true; // slope and intercept are integers
    double slope = 1, inter = 0;      // as in the header
    int sform_code = 0, qform_code = 0;
    std::string transform;     // "sform", "qform" or "pixdim" (the one used)
    double units_to_mm = 1;    // xyz_units: metres 1000, microns 0.001, else 1
    double file_affine[12] = {1, 0, 0, 0, 0, 1, 0, 0, 0, 0, 1, 0}; // (i, j, k) -> RAS mm, as in the file
    double spacing[3] = {1, 1, 1};    // |pixdim| in mm (positive)
    // the grid's own frame: positions p = origin + index * spacing;
    // world = L p + t, L = F A diag(1/spacing), F = diag(-1, -1, 1) for LPS
    double linear[9] = {1, 0, 0, 0, 1, 0, 0, 0, 1}; // L, row-major
    double world_origin[3] = {0, 0, 0}; // world position of voxel (0, 0, 0)
    double origin[3] = {0, 0, 0};       // L^-1 world_origin
    double affine[12] = {1, 0, 0, 0, 0, 1, 0, 0, 0, 0, 1, 0}; // own frame -> world
    bool identity = true;
    int axes = ISOMEND_IO_AXES_PATIENT;
    size_t sample_size() const;
    size_t slice_bytes() const { return (size_t)dims[0] * (size_t)dims[1] * sample_size(); }
};

// Reads and checks the header (see isomend_io.h, "NIfTI"); `axes` is an
// isomend_io_axes.  Throws IoError naming the file.
void nifti_open(const std::string &path, int axes, NiftiVolume &out);

// Places the volume: `world_origin` (the world position of voxel 0, in the
// chosen axes) replaces the file's when `given`; sets origin and affine.
void nifti_place(NiftiVolume &v, const double world_origin[3], bool given);

// Reads the whole volume into `buffer` (slice_bytes() * nz), converted and
// scaled; `progress` (calling thread) returns true to cancel.
void nifti_read(const NiftiVolume &v, void *buffer, const std::function<bool(double)> &progress);

// Reads slice k into `out` (slice_bytes()).
void nifti_read_slice(const NiftiVolume &v, int64_t k, void *out);

} // namespace isomend_io

#endif
