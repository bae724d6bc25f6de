// dicom.hpp - the DICOM series reader's private interface (dicom.cpp, GDCM).
//
// Kept apart from the OpenImageIO stack reader (stack.cpp, resolve.cpp) so
// that libisomend_io has DICOM whichever image backend it is built with:
// nothing here includes OpenImageIO.  api.cpp decides whether a source is
// DICOM (by content), calls dicom_open() and routes reads here.
#ifndef ISOMEND_IO_DICOM_HPP
#define ISOMEND_IO_DICOM_HPP

#include <cstdint>
#include <functional>
#include <string>
#include <vector>

#include "internal.hpp"
#include "isomend_io.h"

namespace isomend_io {

// True when the file starts with the 128-byte preamble and "DICM".
bool is_dicom_file(const std::string &path);

// The candidate files of a DICOM source and what was left out on the way.
struct DicomFiles {
    std::string label;              // the source as given (messages)
    std::vector<std::string> files; // DICOM by content (or named by a DICOMDIR)
    int64_t non_dicom = 0;          // files that are not DICOM, ignored
    bool explicit_list = false;     // the user's list: a non-DICOM file is an error
};

// A folder's DICOM files: its DICOMDIR's images if it has one, else its
// DICOM files (by content), at the top level or, with `recursive`, in its
// subfolders too (hidden entries skipped, 16 levels at most).  False when
// there is none.
bool dicom_folder_files(const std::string &dir, bool recursive, DicomFiles &out);

// True for a DICOMDIR (Media Storage SOP Class 1.2.840.10008.1.3.10, or the
// file name DICOMDIR); then `out` receives the image files it references.
bool dicomdir_files(const std::string &path, DicomFiles &out);

struct DicomSeriesEntry {
    std::string uid, description, modality;
    int64_t number = -1, files = 0, images = 0, columns = 0, rows = 0;
};

struct DicomFrame {
    std::string path;
    int64_t frame = 0;          // frame index in its file (0 for single-frame files)
    double position[3] = {0, 0, 0};
    double along = 0;           // position . normal
    double slope = 1, intercept = 0;
};

// An opened series.
struct DicomSeries {
    std::vector<DicomSeriesEntry> series; // every series found, in list order
    int64_t chosen = -1;
    int64_t non_image = 0, non_dicom = 0, other_series = 0;

    std::vector<DicomFrame> frames; // the chosen series' slices, sorted along the normal
    int64_t files = 0;
    bool multiframe = false;
    int width = 0, height = 0;
    int bits_allocated = 0, bits_stored = 0, high_bit = 0;
    bool pixel_signed = false, monochrome1 = false;
    int64_t smin = 0, smax = 0;    // the stored range Bits Stored allows
    bool rescaled = false, integer_rescale = true, hounsfield = false;
    std::string modality, uid, description, ts_uid, ts_name, photometric;
    isomend_type type = ISOMEND_U16;
    double spacing[3] = {1, 1, 1};
    int spacing_source[3] = {0, 0, 0};
    double orientation[6] = {1, 0, 0, 0, 1, 0};
    double normal[3] = {0, 0, 1};
    double position[3] = {0, 0, 0};   // P0
    double rotation[9] = {1, 0, 0, 0, 1, 0, 0, 0, 1}; // R, row-major; columns row, column, normal
    double origin[3] = {0, 0, 0};     // R^-1 P0: the volume's origin in its own frame
    double affine[12] = {1, 0, 0, 0, 0, 1, 0, 0, 0, 0, 1, 0}; // own frame -> world
    bool identity = true;
    int axes = ISOMEND_IO_AXES_PATIENT;
    // where the slices are, in the series' own frame: uniform (origin and
    // spacing), or each slice's origin (dot(row, P), dot(column, P), dot(n, P))
    SliceGeometry geometry;
    size_t sample_size() const;
    size_t slice_bytes() const { return (size_t)width * (size_t)height * sample_size(); }
};

struct DicomOptions {
    std::string series;        // UID, 1-based position, or "" for the only one
    int axes = ISOMEND_IO_AXES_PATIENT;
    int threads = 0;
    bool spacing_given = false; // options.spacing: a missing Pixel Spacing is no error
};

// Reads every candidate's header, groups by series, chooses one, sorts and
// validates it, and measures where its slices are (see isomend_io.h, "DICOM").  Throws IoError (ISOMEND_IO_ERR_SERIES
// with `out.series` filled when the choice is missing or wrong).  `progress`
// (0..1, calling thread) may throw to cancel.
void dicom_open(const DicomFiles &in, const DicomOptions &o, DicomSeries &out,
                const std::function<void(double)> &progress);

// Decodes the whole series into `buffer` (slice_bytes() * slices) with
// `threads` workers; `progress` (calling thread) returns true to cancel.
void dicom_read(const DicomSeries &s, void *buffer, int threads,
                const std::function<bool(double)> &progress);

// Decodes slice k into `out` (slice_bytes()).
void dicom_read_slice(const DicomSeries &s, int64_t k, void *out);

} // namespace isomend_io

#endif
