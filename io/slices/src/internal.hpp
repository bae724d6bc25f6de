// internal.hpp - the slice-stack importer's private declarations.
//
// The importer is in three parts:
//   resolve.cpp  turns what the user typed (folder, glob, printf pattern,
//                list, one multi-page file) into an ordered list of slices;
//   stack.cpp    opens every slice's header and checks that they agree (size,
//                data window, channels, type, depth), reads slices (checking
//                every decode), and reads whole stacks with worker threads
//                while the calling thread reports progress; it reaches the
//                image library only through image.hpp (OpenImageIO, or
//                libtiff/OpenEXR/libpng directly);
//   api.cpp      the C API: the handle, exception barriers, analysis (range,
//                histogram, Otsu) and the one-call extraction.
// Errors travel as IoError (status + message naming the file); only api.cpp
// turns them into status codes, so no exception ever crosses the C boundary.
#ifndef ISOMEND_IO_INTERNAL_HPP
#define ISOMEND_IO_INTERNAL_HPP

#include <atomic>
#include <cstdint>
#include <functional>
#include <stdexcept>
#include <string>
#include <vector>

#include "isomend_io.h"

namespace isomend_io {

struct IoError : std::runtime_error {
    isomend_io_status status;
    IoError(isomend_io_status s, const std::string &msg) : std::runtime_error(msg), status(s) {}
};

// One slice: a file and the subimage (page / part) in it.
struct Slice {
    std::string path;
    int subimage = 0;
    bool multipage = false; // pages of one file: messages name the page
    // For a page of a multi-page TIFF: where its IFD is, so that it can be
    // opened directly (0: reach it with seek_subimage(), O(page) in OIIO 2.4).
    uint64_t ifd = 0;
    bool big_tiff = false, big_endian = false;
    bool no_bits_tag = false; // the page has no BitsPerSample tag (set with ifd)
};

// Locates every page's IFD of a multi-page TIFF and stores it in `slices`
// (pages of `path`, in order); leaves them unset if the file is not a TIFF or
// the IFD chain does not have one IFD per slice.
void locate_tiff_pages(std::vector<Slice> &slices);

// The threads that read slices: `threads` when positive, else the cores the
// process may run on (isomend_cores(): its affinity mask), at most 8.
int reader_threads_for(int threads);

// ---- resolve.cpp ----
// Natural "less than": digit runs compare as numbers, the rest case-insensitively.
bool natural_less(const std::string &a, const std::string &b);
// True if `path` contains one printf integer conversion (%d, %05d, %i, %u).
bool is_printf_pattern(const std::string &path);
// Formats a printf pattern with one integer (our own formatter: the user's
// string is never passed to the C library's printf).
std::string format_pattern(const std::string &pattern, int64_t index);
bool has_glob_chars(const std::string &path);
bool is_directory(const std::string &path);
bool is_regular_file(const std::string &path);
// Lists a folder's images with the most common image extension, naturally sorted.
std::vector<std::string> list_folder(const std::string &dir);
// Expands a glob (files only), naturally sorted.
std::vector<std::string> expand_glob(const std::string &pattern);
// Expands a printf pattern with first/count/step (count 0 = until missing).
std::vector<std::string> expand_pattern(const std::string &pattern, int64_t first, int64_t count,
                                        int64_t step);
std::string lower_extension(const std::string &path);

// ---- tiff_layout.cpp ----
// The page structure of a TIFF file, read directly (no image library): the
// offset of every page's IFD and whether the page lacks a BitsPerSample tag.
// Classic and BigTIFF, either byte order; an unreadable structure returns
// what was read so far (the image library reports real damage itself).
struct TiffLayout {
    bool big_tiff = false, big_endian = false;
    std::vector<uint64_t> ifd;   // offset of every page's IFD
    std::vector<bool> no_bits;   // page lacks BitsPerSample
};
TiffLayout tiff_layout(const std::string &path);

// ---- stack.cpp ----
enum class Sample; // image.hpp

struct StackInfo {
    int width = 0, height = 0;        // data window size
    int xorigin = 0, yorigin = 0;     // data window origin
    int file_channels = 0;            // channels in the file
    int channel = 0;                  // channel read (or first of R,G,B for luma)
    int luma_channels[3] = {0, 1, 2}; // R, G, B for luma
    bool luma = false;
    Sample file_type{};               // stored type of the channel read
    int bits = 0;                     // stored bits per sample (12 for packed 12-bit)
    bool u32_to_f64 = false;          // uint32 delivered as f64
    isomend_type type = ISOMEND_U8;   // delivered type
    std::string format;               // format name of the first slice ("tiff", ...)
    double spacing[3] = {1, 1, 1};
    int spacing_source[3] = {0, 0, 0};
    size_t sample_size() const;
    size_t slice_bytes() const { return (size_t)width * (size_t)height * sample_size(); }
};

// "path" or "path (page k)": how messages name a slice.
std::string slice_name(const Slice &s);

// Opens every slice's header and checks that it agrees with the first;
// fills `info` (spacing from the first slice's metadata).  `channel` is the
// option (ISOMEND_IO_CHANNEL_*); `threads` as for read_parallel.  `progress`
// is called on the calling thread with 0..1 and may throw to cancel.
void scan_stack(const std::vector<Slice> &slices, int channel, int threads, StackInfo &info,
                const std::function<void(double)> &progress);

// Reads one slice into `out` (info.slice_bytes()), checking it against info.
void read_slice(const Slice &slice, const StackInfo &info, void *out);

// Reads slices [0, n) with `threads` workers; each decoded slice is handed to
// `sink(k, data)` on the worker thread (sink must be thread-safe for distinct
// k).  The calling thread calls `progress(fraction)` and stops everything when
// it returns true (then throws IoError CANCELLED).  On an error the workers
// stop taking slices; the error of the lowest slice index among those read
// is rethrown after all workers have stopped.
// `target(k)` (may be empty, or return nullptr) gives where slice k is decoded
// directly; otherwise it is decoded into a per-worker buffer.
void read_parallel(const std::vector<Slice> &slices, const StackInfo &info, int threads,
                   const std::function<void *(int64_t)> &target,
                   const std::function<void(int64_t, const void *)> &sink,
                   const std::function<bool(double)> &progress);

// ---- geometry.cpp ----
// Where the slices are (isomend_io_geometry, isomend_volume.slice_origins).
struct SliceGeometry {
    bool uniform = true;
    double gap_median = 0, gap_min = 0, gap_max = 0; // along z
    double tilt_degrees = 0, max_offset = 0;
    int64_t long_gaps = 0, uneven_gaps = 0;
    int64_t longest = -1;        // k of the longest gap over 1.5x the median (k to k+1), -1 if none
    std::vector<double> origins; // 3 a slice when not uniform, else empty
    std::string warning;         // "" or one line (DICOM only)
};

// Measures the slice origins (3 a slice, z strictly increasing, at least two
// slices): gaps along z, tilt, the largest distance from the evenly spaced
// grid origin0 + k * mean gap along z; uniform when that is <= tolerance
// (then g.origins is empty, else it receives `origins`).  Sets no warning.
void measure_slices(std::vector<double> origins, double tolerance, SliceGeometry &g);

// An evenly spaced grid with this gap.
void measure_uniform(double gap, SliceGeometry &g);

// The one-line warning for uneven or long gaps ("" if none): "slice gaps vary
// from A to B mm (median M mm): <meshed>[; a gap of ... between slice
// <slice_name(k)> and <slice_name(k+1)> is Rx the median: a missing slice?]".
std::string gap_warning(const SliceGeometry &g, const std::string &meshed,
                        const std::function<std::string(int64_t)> &slice_name);

} // namespace isomend_io

#endif
