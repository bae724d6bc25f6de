// api.cpp - the C API of isomend_io: handle, exception barrier, analysis and
// the one-call extraction.
//
// Every exported function runs its body inside guard(): IoError becomes its
// status and message, std::bad_alloc becomes ISOMEND_IO_ERR_OUT_OF_MEMORY,
// anything else ISOMEND_IO_ERR_INTERNAL.  No exception crosses the C
// boundary, so ctypes and MeshLab callers only ever see status codes.
//
// Raw and NRRD sources are delegated to io/common's readers
// (volume_readers.h), so the command line, this library and the plug-ins
// read them with the same code and give the same messages.
#include "dicom.hpp"
#include "image.hpp"
#include "nifti.hpp"

#include <algorithm>
#include <chrono>
#include <cinttypes>
#include <cmath>
#include <cstdio>
#include <cstring>
#include <fstream>
#include <memory>
#include <mutex>
#include <new>
#include <system_error>
#include <thread>

#include "label_samples.h"
#include "label_table.h"
#include "volume_readers.h"

using namespace isomend_io;

struct isomend_io_source {
    std::string message;
    bool opened = false;
    bool open_attempted = false;
    bool in_job = false; // a job has it, from isomend_io_job_start to _finish
    int kind = -1;
    isomend_io_options opts{};
    std::vector<Slice> slices;
    StackInfo info;
    bool is_file_volume = false; // raw or NRRD through io/common
    isomend_fileio_info file_info{};
    double origin[3] = {0, 0, 0};
    std::unique_ptr<char[]> volume;
    bool loaded = false;
    double load_seconds = 0;
    bool analysed = false;
    isomend_io_summary summary{};
    double otsu = 0;                     // Otsu's level (the suggestion unless CT)
    // DICOM: the choices made before opening, the series found, the one opened
    std::string series_choice;
    int axes = ISOMEND_IO_AXES_PATIENT;
    std::vector<DicomSeriesEntry> series_found;
    std::unique_ptr<DicomSeries> dicom;
    std::unique_ptr<NiftiVolume> nifti; // a NIfTI volume (nifti.cpp)
    // options.slice_positions, copied at open; where the slices are (every source)
    std::vector<double> positions;
    SliceGeometry geometry;
};

namespace {

template <typename F> isomend_io_status guard(isomend_io_source *src, F &&body) {
    try {
        if (src) src->message.clear();
        body();
        return ISOMEND_IO_OK;
    } catch (const IoError &e) {
        if (src) src->message = e.what();
        return e.status;
    } catch (const std::bad_alloc &) {
        if (src) src->message = "out of memory";
        return ISOMEND_IO_ERR_OUT_OF_MEMORY;
    } catch (const std::exception &e) {
        if (src) src->message = std::string("internal error: ") + e.what();
        return ISOMEND_IO_ERR_INTERNAL;
    } catch (...) {
        if (src) src->message = "internal error: unknown exception";
        return ISOMEND_IO_ERR_INTERNAL;
    }
}

void require_open(const isomend_io_source *src) {
    if (!src->opened)
        throw IoError(ISOMEND_IO_ERR_INVALID_ARGUMENT, "the source is not open (call isomend_io_open first)");
}

isomend_io_status from_fileio(isomend_fileio_status s) {
    switch (s) {
    case ISOMEND_FILEIO_OK: return ISOMEND_IO_OK;
    case ISOMEND_FILEIO_ERR_INVALID_ARGUMENT: return ISOMEND_IO_ERR_INVALID_ARGUMENT;
    case ISOMEND_FILEIO_ERR_NOT_FOUND: return ISOMEND_IO_ERR_NOT_FOUND;
    case ISOMEND_FILEIO_ERR_UNREADABLE: return ISOMEND_IO_ERR_UNREADABLE;
    case ISOMEND_FILEIO_ERR_FORMAT: return ISOMEND_IO_ERR_UNREADABLE;
    case ISOMEND_FILEIO_ERR_UNSUPPORTED: return ISOMEND_IO_ERR_UNSUPPORTED;
    case ISOMEND_FILEIO_ERR_SIZE: return ISOMEND_IO_ERR_CORRUPT;
    case ISOMEND_FILEIO_ERR_CORRUPT: return ISOMEND_IO_ERR_CORRUPT;
    case ISOMEND_FILEIO_ERR_OUT_OF_MEMORY: return ISOMEND_IO_ERR_OUT_OF_MEMORY;
    case ISOMEND_FILEIO_ERR_CANCELLED: return ISOMEND_IO_ERR_CANCELLED;
    default: return ISOMEND_IO_ERR_INTERNAL;
    }
}

void check_fileio(isomend_fileio_status s, const char *msg) {
    if (s != ISOMEND_FILEIO_OK) throw IoError(from_fileio(s), msg);
}

struct FileProgress {
    isomend_io_progress_fn fn;
    void *user;
    int stage;
};

int file_progress(void *user, double f) {
    auto *p = (FileProgress *)user;
    return p->fn ? p->fn(p->user, p->stage, f) : 0;
}

std::string human_bytes(uint64_t b) {
    char buf[64];
    if (b >= (1ull << 30)) std::snprintf(buf, sizeof buf, "%.2f GiB", (double)b / (double)(1ull << 30));
    else if (b >= (1ull << 20)) std::snprintf(buf, sizeof buf, "%.1f MiB", (double)b / (double)(1ull << 20));
    else std::snprintf(buf, sizeof buf, "%" PRIu64 " bytes", b);
    return buf;
}

// MemAvailable from /proc/meminfo, 0 if unknown.
uint64_t memory_available() {
    std::ifstream f("/proc/meminfo");
    std::string key;
    uint64_t kb = 0;
    std::string unit;
    while (f >> key >> kb >> unit) {
        if (key == "MemAvailable:") return kb * 1024;
    }
    return 0;
}

int64_t dim(const isomend_io_source *s, int a) {
    if (s->is_file_volume) return s->file_info.dims[a];
    if (a == 0) return s->info.width;
    if (a == 1) return s->info.height;
    return (int64_t)s->slices.size();
}

isomend_type src_type(const isomend_io_source *s) {
    return s->is_file_volume ? s->file_info.type : s->info.type;
}

uint64_t slice_bytes(const isomend_io_source *s) {
    // dims are < 2^31 each (the image libraries' ints), so x*y < 2^62; saturate the last product
    uint64_t xy = (uint64_t)dim(s, 0) * (uint64_t)dim(s, 1);
    uint64_t size = isomend_type_size(src_type(s));
    return xy > UINT64_MAX / size ? UINT64_MAX : xy * size;
}

uint64_t volume_bytes(const isomend_io_source *s) {
    uint64_t sb = slice_bytes(s);
    uint64_t nz = (uint64_t)dim(s, 2);
    if (sb && nz > UINT64_MAX / sb) return UINT64_MAX;
    return sb * nz;
}

std::string dims_text(const isomend_io_source *s) {
    return std::to_string(dim(s, 0)) + "x" + std::to_string(dim(s, 1)) + "x" + std::to_string(dim(s, 2)) +
           " " + isomend_type_name(src_type(s));
}

int reader_threads(const isomend_io_source *s) {
    return reader_threads_for(s->opts.threads);
}

// Refuses `need` bytes (described by `what`) beyond the limit, before allocating.
void check_memory_for(const isomend_io_source *s, uint64_t need, const std::string &what_needs) {
    uint64_t limit = s->opts.memory_limit;
    const char *what = "the memory limit";
    if (limit == 0) {
        limit = memory_available();
        what = "the memory available (MemAvailable)";
    }
    if ((limit && need > limit) || need > (uint64_t)SIZE_MAX / 2)
        throw IoError(ISOMEND_IO_ERR_TOO_LARGE, what_needs + " needs " + human_bytes(need) + ", more than " +
                                                    what + " of " + human_bytes(limit));
}

void check_memory(const isomend_io_source *s) {
    uint64_t need = volume_bytes(s);
    uint64_t limit = s->opts.memory_limit;
    const char *what = "the memory limit";
    if (limit == 0) {
        limit = memory_available();
        what = "the memory available (MemAvailable)";
    }
    if ((limit && need > limit) || need > (uint64_t)SIZE_MAX / 2)
        throw IoError(ISOMEND_IO_ERR_TOO_LARGE,
                      "volume " + dims_text(s) + " needs " + human_bytes(need) + ", more than " + what +
                          " of " + human_bytes(limit) +
                          "; crop the stack (--first/--count/--step) or free memory");
}

void read_file_slices(isomend_io_source *s, int64_t first, int64_t count, void *buf, size_t size,
                      isomend_io_progress_fn fn, void *user) {
    char msg[ISOMEND_FILEIO_MSG_SIZE];
    msg[0] = 0;
    FileProgress p{fn, user, ISOMEND_IO_STAGE_READ};
    check_fileio(isomend_fileio_read(&s->file_info, first, count, buf, size, fn ? file_progress : nullptr,
                                     &p, msg, sizeof msg),
                 msg);
}

// A NRRD whose "space directions" point an axis backwards (NIfTI-derived
// RAS data) is delivered reversed along that axis, so that for every source
// world = origin + index * spacing with positive spacing, as io/common's
// isomend_fileio_describe() presents it to the CLI: same mesh, unmirrored.
// Reverses x and y inside `count` consecutive slices.
void reverse_in_slices(const isomend_io_source *s, void *buf, int64_t count) {
    const int *neg = s->file_info.axis_negative;
    if (!neg[0] && !neg[1]) return;
    const size_t es = isomend_type_size(src_type(s));
    const size_t nx = (size_t)dim(s, 0), ny = (size_t)dim(s, 1), row = nx * es;
    std::vector<unsigned char> tmp(std::max(row, es));
    for (int64_t k = 0; k < count; k++) {
        unsigned char *slice = (unsigned char *)buf + (size_t)k * ny * row;
        if (neg[1]) {
            for (size_t y = 0; y < ny / 2; y++) {
                unsigned char *a = slice + y * row, *b = slice + (ny - 1 - y) * row;
                std::memcpy(tmp.data(), a, row);
                std::memcpy(a, b, row);
                std::memcpy(b, tmp.data(), row);
            }
        }
        if (neg[0]) {
            for (size_t y = 0; y < ny; y++) {
                unsigned char *r = slice + y * row;
                for (size_t x = 0; x < nx / 2; x++) {
                    unsigned char *a = r + x * es, *b = r + (nx - 1 - x) * es;
                    std::memcpy(tmp.data(), a, es);
                    std::memcpy(a, b, es);
                    std::memcpy(b, tmp.data(), es);
                }
            }
        }
    }
}

// Reads delivered slice k of a raw/NRRD source (stored slice nz-1-k along a negative z).
void read_file_slice(isomend_io_source *s, int64_t k, void *buf, size_t size) {
    int64_t stored = s->file_info.axis_negative[2] ? dim(s, 2) - 1 - k : k;
    read_file_slices(s, stored, 1, buf, size, nullptr, nullptr);
    reverse_in_slices(s, buf, 1);
}

// Reads the whole raw/NRRD volume in delivered order.
void read_file_volume(isomend_io_source *s, void *buffer, size_t size, isomend_io_progress_fn fn,
                      void *user) {
    read_file_slices(s, 0, dim(s, 2), buffer, size, fn, user);
    reverse_in_slices(s, buffer, dim(s, 2));
    if (s->file_info.axis_negative[2]) {
        const size_t sb = (size_t)slice_bytes(s);
        const int64_t nz = dim(s, 2);
        std::vector<unsigned char> tmp(sb);
        for (int64_t k = 0; k < nz / 2; k++) {
            unsigned char *a = (unsigned char *)buffer + (size_t)k * sb;
            unsigned char *b = (unsigned char *)buffer + (size_t)(nz - 1 - k) * sb;
            std::memcpy(tmp.data(), a, sb);
            std::memcpy(a, b, sb);
            std::memcpy(b, tmp.data(), sb);
        }
    }
}

void do_read(isomend_io_source *s, void *buffer, size_t size, isomend_io_progress_fn fn, void *user) {
    uint64_t need = volume_bytes(s);
    if (!buffer || size < need)
        throw IoError(ISOMEND_IO_ERR_INVALID_ARGUMENT,
                      "buffer of " + std::to_string(size) + " bytes is too small for " + dims_text(s) +
                          " (" + std::to_string(need) + " bytes)");
    if (s->is_file_volume) {
        read_file_volume(s, buffer, size, fn, user);
        return;
    }
    if (s->nifti) {
        nifti_read(*s->nifti, buffer,
                   [&](double f) -> bool { return fn ? fn(user, ISOMEND_IO_STAGE_READ, f) != 0 : false; });
        return;
    }
    if (s->dicom) {
        dicom_read(*s->dicom, buffer, s->opts.threads,
                   [&](double f) -> bool { return fn ? fn(user, ISOMEND_IO_STAGE_READ, f) != 0 : false; });
        return;
    }
    const size_t sb = (size_t)slice_bytes(s);
    read_parallel(
        s->slices, s->info, s->opts.threads,
        [&](int64_t k) -> void * { return (char *)buffer + (size_t)k * sb; }, nullptr,
        [&](double f) -> bool { return fn ? fn(user, ISOMEND_IO_STAGE_READ, f) != 0 : false; });
}

// ---- analysis ----

template <typename T> void range_of(const void *p, size_t n, double &mn, double &mx, uint64_t &bad) {
    const T *v = (const T *)p;
    for (size_t i = 0; i < n; i++) {
        double d = (double)v[i];
        if (!std::isfinite(d)) {
            bad++;
            continue;
        }
        if (d < mn) mn = d;
        if (d > mx) mx = d;
    }
}

void range_any(isomend_type t, const void *p, size_t n, double &mn, double &mx, uint64_t &bad) {
    switch (t) {
    case ISOMEND_U8: range_of<uint8_t>(p, n, mn, mx, bad); break;
    case ISOMEND_I8: range_of<int8_t>(p, n, mn, mx, bad); break;
    case ISOMEND_U16: range_of<uint16_t>(p, n, mn, mx, bad); break;
    case ISOMEND_I16: range_of<int16_t>(p, n, mn, mx, bad); break;
    case ISOMEND_I32: range_of<int32_t>(p, n, mn, mx, bad); break;
    case ISOMEND_F32: range_of<float>(p, n, mn, mx, bad); break;
    case ISOMEND_F64: range_of<double>(p, n, mn, mx, bad); break;
    }
}

constexpr int kOtsuBins = 256;
// options.slice_positions within this fraction of the mean gap of evenly
// spaced are a uniform grid (isomend_io.h)
constexpr double kPositionsTolerance = 1e-6;
// CT levels in Hounsfield units (docs/dicom.md says where they come from).
constexpr double kBoneHU = 300.0;
constexpr double kSkinHU = -500.0;

struct Hist {
    uint64_t coarse[ISOMEND_IO_HISTOGRAM_BINS] = {};
    uint64_t fine[kOtsuBins] = {};
};

int bin_of(double d, double mn, double mx, int bins) {
    if (!(mx > mn)) return 0;
    int b = (int)((d - mn) / (mx - mn) * bins);
    return b < 0 ? 0 : (b >= bins ? bins - 1 : b);
}

template <typename T> void hist_of(const void *p, size_t n, double mn, double mx, Hist &h) {
    const T *v = (const T *)p;
    for (size_t i = 0; i < n; i++) {
        double d = (double)v[i];
        if (!std::isfinite(d)) continue;
        h.coarse[bin_of(d, mn, mx, ISOMEND_IO_HISTOGRAM_BINS)]++;
        h.fine[bin_of(d, mn, mx, kOtsuBins)]++;
    }
}

void hist_any(isomend_type t, const void *p, size_t n, double mn, double mx, Hist &h) {
    switch (t) {
    case ISOMEND_U8: hist_of<uint8_t>(p, n, mn, mx, h); break;
    case ISOMEND_I8: hist_of<int8_t>(p, n, mn, mx, h); break;
    case ISOMEND_U16: hist_of<uint16_t>(p, n, mn, mx, h); break;
    case ISOMEND_I16: hist_of<int16_t>(p, n, mn, mx, h); break;
    case ISOMEND_I32: hist_of<int32_t>(p, n, mn, mx, h); break;
    case ISOMEND_F32: hist_of<float>(p, n, mn, mx, h); break;
    case ISOMEND_F64: hist_of<double>(p, n, mn, mx, h); break;
    }
}

bool is_integer_type(isomend_type t) { return t != ISOMEND_F32 && t != ISOMEND_F64; }

// Otsu (1979) on the fine histogram, shared with the command line (io/common).
double otsu(const uint64_t *h, int bins, double mn, double mx, bool integer) {
    return isomend_fileio_otsu(h, bins, mn, mx, integer ? 1 : 0);
}

void do_load(isomend_io_source *s, isomend_volume *vol, double *seconds);

// Calls f(data, samples) for every slice: from the loaded volume, else
// streamed (worker threads for image stacks, flat memory).
template <typename F> void for_each_slice(isomend_io_source *s, F &&f, double base, double part) {
    const size_t n = (size_t)dim(s, 0) * (size_t)dim(s, 1);
    const size_t sb = (size_t)slice_bytes(s);
    isomend_io_progress_fn fn = s->opts.progress;
    void *user = s->opts.progress_user;
    if (!s->loaded && ((s->is_file_volume && s->file_info.encoding == ISOMEND_FILEIO_ENC_GZIP) || s->dicom ||
                       (s->nifti && s->nifti->gzip))) {
        // Slice k of a gzip stream costs decompressing slices 0..k (and a
        // frame of a DICOM file decoding the file): load once (with the
        // memory check) rather than stream in quadratic time.
        do_load(s, nullptr, nullptr);
    }
    if (s->loaded) {
        for (int64_t k = 0; k < dim(s, 2); k++) f(s->volume.get() + (size_t)k * sb, n);
        return;
    }
    // Streaming keeps one slice per reader thread in memory: check that much.
    uint64_t workers = s->is_file_volume || s->nifti ? 1 : (uint64_t)reader_threads(s);
    check_memory_for(s, sb > 0 && workers > UINT64_MAX / sb ? UINT64_MAX : sb * workers,
                     std::to_string(workers) + " slice buffer(s) of " + std::to_string(dim(s, 0)) + "x" +
                         std::to_string(dim(s, 1)) + " " + isomend_type_name(src_type(s)));
    std::mutex mu;
    if (s->is_file_volume || s->nifti) { // one file: its slices in order, one buffer
        std::vector<char> buf(sb);
        for (int64_t k = 0; k < dim(s, 2); k++) {
            if (s->nifti) nifti_read_slice(*s->nifti, k, buf.data());
            else read_file_slice(s, k, buf.data(), buf.size());
            f(buf.data(), n);
            if (fn && fn(user, ISOMEND_IO_STAGE_ANALYSE, base + part * (double)(k + 1) / (double)dim(s, 2)))
                throw IoError(ISOMEND_IO_ERR_CANCELLED, "cancelled while analysing");
        }
        return;
    }
    read_parallel(
        s->slices, s->info, s->opts.threads, nullptr,
        [&](int64_t, const void *p) {
            std::lock_guard<std::mutex> lock(mu);
            f(p, n);
        },
        [&](double fr) -> bool { return fn ? fn(user, ISOMEND_IO_STAGE_ANALYSE, base + part * fr) != 0 : false; });
}

void do_analyse(isomend_io_source *s) {
    if (s->analysed) return;
    auto t0 = std::chrono::steady_clock::now();
    const isomend_type t = src_type(s);
    double mn = INFINITY, mx = -INFINITY;
    uint64_t bad = 0;
    for_each_slice(s, [&](const void *p, size_t n) { range_any(t, p, n, mn, mx, bad); }, 0.0, 0.5);
    if (!(mn <= mx)) mn = mx = 0;
    Hist h;
    for_each_slice(s, [&](const void *p, size_t n) { hist_any(t, p, n, mn, mx, h); }, 0.5, 0.5);
    isomend_io_summary &sum = s->summary;
    sum = isomend_io_summary{};
    sum.min = mn;
    sum.max = mx;
    sum.samples = (uint64_t)dim(s, 0) * (uint64_t)dim(s, 1) * (uint64_t)dim(s, 2);
    sum.nan_samples = bad;
    std::memcpy(sum.histogram, h.coarse, sizeof h.coarse);
    s->otsu = otsu(h.fine, kOtsuBins, mn, mx, is_integer_type(t));
    sum.suggested_iso = s->dicom && s->dicom->hounsfield ? kBoneHU : s->otsu;
    sum.read_seconds = s->loaded ? s->load_seconds
                                 : std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
    s->analysed = true;
}

void do_load(isomend_io_source *s, isomend_volume *vol, double *seconds) {
    require_open(s);
    if (!s->loaded) {
        check_memory(s);
        uint64_t need = volume_bytes(s);
        s->volume.reset(new (std::nothrow) char[(size_t)need]);
        if (!s->volume)
            throw IoError(ISOMEND_IO_ERR_OUT_OF_MEMORY,
                          "cannot allocate " + human_bytes(need) + " for volume " + dims_text(s));
        auto t0 = std::chrono::steady_clock::now();
        try {
            do_read(s, s->volume.get(), (size_t)need, s->opts.progress, s->opts.progress_user);
        } catch (...) {
            s->volume.reset();
            throw;
        }
        s->load_seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
        s->loaded = true;
    }
    if (vol) {
        isomend_volume_init(vol, s->volume.get(), src_type(s), dim(s, 0), dim(s, 1), dim(s, 2));
        double sp[3];
        for (int a = 0; a < 3; a++) sp[a] = s->is_file_volume ? s->file_info.spacing[a] : s->info.spacing[a];
        for (int a = 0; a < 3; a++) {
            vol->spacing[a] = sp[a];
            vol->origin[a] = s->origin[a];
        }
        vol->slice_origins = s->geometry.origins.empty() ? nullptr : s->geometry.origins.data();
    }
    if (seconds) *seconds = s->load_seconds;
}

void apply_overrides(isomend_io_source *s) {
    const isomend_io_options &o = s->opts;
    bool sp_given = o.spacing[0] > 0 && o.spacing[1] > 0 && o.spacing[2] > 0;
    bool sp_any = o.spacing[0] != 0 || o.spacing[1] != 0 || o.spacing[2] != 0;
    if (sp_any && !sp_given)
        throw IoError(ISOMEND_IO_ERR_INVALID_ARGUMENT, "spacing must be three values > 0");
    for (int a = 0; a < 3; a++) {
        if (!std::isfinite(o.spacing[a]) || !std::isfinite(o.origin[a]))
            throw IoError(ISOMEND_IO_ERR_INVALID_ARGUMENT, "spacing and origin must be finite");
    }
    if (sp_given) {
        for (int a = 0; a < 3; a++) {
            s->info.spacing[a] = o.spacing[a];
            s->info.spacing_source[a] = ISOMEND_IO_SPACING_OPTION;
            s->file_info.spacing[a] = o.spacing[a];
        }
    }
    bool origin_given = o.origin[0] != 0 || o.origin[1] != 0 || o.origin[2] != 0;
    if (s->nifti) {
        // options.origin: the world position of voxel (0, 0, 0), in the chosen axes
        nifti_place(*s->nifti, o.origin, origin_given);
        for (int a = 0; a < 3; a++) s->origin[a] = s->nifti->origin[a];
        return;
    }
    if (s->dicom) {
        DicomSeries &d = *s->dicom;
        const double before[3] = {d.origin[0], d.origin[1], d.origin[2]};
        if (origin_given) {
            // the world position of sample (0, 0, 0), in the series' own frame
            // and, through the rotation, in patient space
            const double *R = d.rotation;
            bool rotated = d.axes == ISOMEND_IO_AXES_PATIENT && !d.identity;
            for (int a = 0; a < 3; a++)
                d.origin[a] = rotated ? R[a] * o.origin[0] + R[3 + a] * o.origin[1] + R[6 + a] * o.origin[2]
                                      : o.origin[a];
            if (rotated)
                for (int r = 0; r < 3; r++)
                    d.affine[4 * r + 3] = o.origin[r] - (R[3 * r] * d.origin[0] + R[3 * r + 1] * d.origin[1] +
                                                         R[3 * r + 2] * d.origin[2]);
        }
        for (int a = 0; a < 3; a++) s->origin[a] = d.origin[a];
        // the slice origins move with the origin (the same frame)
        std::vector<double> &t = d.geometry.origins;
        for (size_t i = 0; i < t.size(); i++) t[i] += d.origin[i % 3] - before[i % 3];
        s->geometry = d.geometry;
        return;
    }
    for (int a = 0; a < 3; a++) {
        if (origin_given || !s->is_file_volume) {
            s->origin[a] = o.origin[a];
        } else {
            // samples are delivered reversed along a negative axis (see
            // reverse_negative_axes): sample 0 is the stored last one
            double last = (double)(s->file_info.dims[a] - 1) * s->file_info.spacing[a];
            s->origin[a] = s->file_info.origin[a] - (s->file_info.axis_negative[a] ? last : 0.0);
        }
    }
}

// The caller's slice positions (options.slice_positions, validated and copied
// into s->positions by do_open) for a stack or a raw/NRRD volume, after the
// overrides: evenly spaced within 1e-6 of the mean gap, they become that
// spacing and origin; otherwise the table of slice origins (origin x, origin
// y, z_k) that isomend_io_load() hands to the core.  Either way spacing[2] is
// the mean gap and origin z the first position.  Without positions: the
// uniform grid of the spacing.
void apply_positions(isomend_io_source *s) {
    double &sz = s->is_file_volume ? s->file_info.spacing[2] : s->info.spacing[2];
    if (s->positions.empty()) {
        measure_uniform(sz, s->geometry);
        return;
    }
    const std::vector<double> &p = s->positions;
    const size_t n = p.size();
    if ((int64_t)n != dim(s, 2))
        throw IoError(ISOMEND_IO_ERR_INVALID_ARGUMENT,
                      "slice_positions: " + std::to_string(n) + " positions for " +
                          std::to_string(dim(s, 2)) +
                          " slices (slice_position_count must be the number of slices of " +
                          std::string(s->is_file_volume ? s->file_info.path : s->slices[0].path) +
                          ")");
    const double mean = (p[n - 1] - p[0]) / (double)(n - 1);
    std::vector<double> origins(3 * n);
    for (size_t k = 0; k < n; k++) {
        origins[3 * k] = s->origin[0];
        origins[3 * k + 1] = s->origin[1];
        origins[3 * k + 2] = p[k];
    }
    measure_slices(std::move(origins), kPositionsTolerance * mean, s->geometry);
    s->info.spacing[2] = s->file_info.spacing[2] = mean;
    s->info.spacing_source[2] = ISOMEND_IO_SPACING_OPTION;
    s->origin[2] = p[0];
}

// options.slice_positions: copied (the caller's array may go away after the
// open), finite and strictly increasing; the count is checked against the
// slices once they are known (apply_positions).
void copy_positions(isomend_io_source *s) {
    isomend_io_options &o = s->opts;
    s->positions.clear();
    if (o.slice_position_count > 0) {
        if (!o.slice_positions)
            throw IoError(ISOMEND_IO_ERR_INVALID_ARGUMENT,
                          "slice_positions is NULL but slice_position_count is " +
                              std::to_string(o.slice_position_count));
        s->positions.assign(o.slice_positions, o.slice_positions + o.slice_position_count);
        const std::vector<double> &p = s->positions;
        for (size_t k = 0; k < p.size(); k++) {
            if (!std::isfinite(p[k]))
                throw IoError(ISOMEND_IO_ERR_INVALID_ARGUMENT,
                              "slice_positions[" + std::to_string(k) + "] is not finite (" +
                                  std::to_string(p[k]) + ")");
            if (k > 0 && !(p[k] > p[k - 1])) {
                char b[160];
                std::snprintf(
                    b, sizeof b,
                    "slice_positions[%zu] = %.17g is not greater than slice_positions[%zu] = %.17g",
                    k, p[k], k - 1, p[k - 1]);
                throw IoError(ISOMEND_IO_ERR_INVALID_ARGUMENT,
                              std::string(b) +
                                  " (the positions must increase strictly, one per slice)");
            }
        }
    }
    o.slice_positions = s->positions.empty() ? nullptr : s->positions.data();
    o.slice_position_count = s->positions.size();
}

void open_file_volume(isomend_io_source *s, const std::string &path, bool nrrd) {
    char msg[ISOMEND_FILEIO_MSG_SIZE];
    msg[0] = 0;
    isomend_fileio_status st;
    if (nrrd) {
        st = isomend_fileio_probe_nrrd(path.c_str(), &s->file_info, msg, sizeof msg);
    } else {
        st = isomend_fileio_probe_raw(path.c_str(), s->opts.raw_dims, s->opts.raw_type,
                                      s->opts.raw_big_endian, s->opts.raw_header, &s->file_info, msg,
                                      sizeof msg);
    }
    check_fileio(st, msg);
    s->is_file_volume = true;
    s->kind = nrrd ? ISOMEND_IO_KIND_NRRD : ISOMEND_IO_KIND_RAW;
    int src = nrrd && s->file_info.spacing_known ? ISOMEND_IO_SPACING_HEADER : ISOMEND_IO_SPACING_DEFAULT;
    for (int a = 0; a < 3; a++) s->info.spacing_source[a] = src;
    s->info.format = nrrd ? "nrrd" : "raw";
    if (s->file_info.dims[0] < 2 || s->file_info.dims[1] < 2 || s->file_info.dims[2] < 2)
        throw IoError(ISOMEND_IO_ERR_TOO_FEW_SLICES,
                      path + ": dimensions " + dims_text(s) + "; every dimension must be at least 2");
}

// A DICOM series (dicom.cpp) presented as a stack: one Slice per frame, so
// that the dimensions and queries are the stack's; reads go to dicom.cpp.
void open_dicom(isomend_io_source *s, const DicomFiles &files) {
    const isomend_io_options &o = s->opts;
    if (!s->positions.empty())
        throw IoError(
            ISOMEND_IO_ERR_INVALID_ARGUMENT,
            "slice_positions: " + files.label +
                " is a DICOM series, whose slices are placed by their own Image Position (Patient) "
                "values; slice positions are for image stacks and raw/NRRD volumes");
    DicomOptions d;
    d.series = s->series_choice;
    d.axes = s->axes;
    d.threads = o.threads;
    d.spacing_given = o.spacing[0] > 0 && o.spacing[1] > 0 && o.spacing[2] > 0;
    s->dicom.reset(new DicomSeries);
    isomend_io_progress_fn fn = o.progress;
    void *user = o.progress_user;
    try {
        dicom_open(files, d, *s->dicom, [&](double f) {
            if (fn && fn(user, ISOMEND_IO_STAGE_OPEN, f))
                throw IoError(ISOMEND_IO_ERR_CANCELLED, "cancelled while opening the DICOM files");
        });
    } catch (...) {
        s->series_found = s->dicom->series;
        s->dicom.reset();
        throw;
    }
    s->series_found = s->dicom->series;
    const DicomSeries &ds = *s->dicom;
    s->kind = ISOMEND_IO_KIND_DICOM;
    s->info = StackInfo{};
    s->info.width = ds.width;
    s->info.height = ds.height;
    s->info.file_channels = 1;
    s->info.type = ds.type;
    s->info.format = "dicom";
    for (int a = 0; a < 3; a++) {
        s->info.spacing[a] = ds.spacing[a];
        s->info.spacing_source[a] = ds.spacing_source[a];
    }
    for (const auto &f : ds.frames) s->slices.push_back(Slice{f.path, (int)f.frame, ds.multiframe});
    apply_overrides(s);
    if (d.spacing_given) { // the slice spacing measured stays the positions' unless overridden
        for (int a = 0; a < 3; a++) s->dicom->spacing[a] = s->info.spacing[a];
    }
    s->opened = true;
}

// A NIfTI volume (nifti.cpp) presented as a stack of its k slices, so that
// the dimensions and queries are the stack's; reads go to nifti.cpp.
void open_nifti(isomend_io_source *s, const std::string &path) {
    if (!s->positions.empty())
        throw IoError(ISOMEND_IO_ERR_INVALID_ARGUMENT,
                      "slice_positions: " + path +
                          " is a NIfTI volume, placed by its own sform/qform; slice positions are for "
                          "image stacks and raw/NRRD volumes");
    if (s->opts.progress && s->opts.progress(s->opts.progress_user, ISOMEND_IO_STAGE_OPEN, 0.0))
        throw IoError(ISOMEND_IO_ERR_CANCELLED, "cancelled while opening " + path);
    s->nifti.reset(new NiftiVolume);
    nifti_open(path, s->axes, *s->nifti);
    const NiftiVolume &v = *s->nifti;
    s->kind = ISOMEND_IO_KIND_NIFTI;
    s->info = StackInfo{};
    s->info.width = (int)v.dims[0];
    s->info.height = (int)v.dims[1];
    s->info.file_channels = 1;
    s->info.type = v.type;
    s->info.format = v.version == 0 ? "analyze" : v.version == 2 ? "nifti2" : "nifti1";
    for (int a = 0; a < 3; a++) {
        s->info.spacing[a] = v.spacing[a];
        s->info.spacing_source[a] = ISOMEND_IO_SPACING_HEADER;
    }
    for (int64_t k = 0; k < v.dims[2]; k++) s->slices.push_back(Slice{v.path, (int)k, true});
    apply_overrides(s);
    measure_uniform(s->info.spacing[2], s->geometry);
    s->opened = true;
}

void do_open(isomend_io_source *s, const char *const *paths, size_t count, const isomend_io_options *opts) {
    if (s->open_attempted)
        throw IoError(ISOMEND_IO_ERR_INVALID_ARGUMENT, "isomend_io_open may be called once per handle");
    s->open_attempted = true;
    if (!paths || count == 0) throw IoError(ISOMEND_IO_ERR_INVALID_ARGUMENT, "no source given");
    for (size_t i = 0; i < count; i++)
        if (!paths[i] || !paths[i][0]) throw IoError(ISOMEND_IO_ERR_INVALID_ARGUMENT, "empty source path");
    if (opts) s->opts = *opts;
    else isomend_io_options_init(&s->opts);
    const isomend_io_options &o = s->opts;
    if (o.channel < ISOMEND_IO_CHANNEL_LUMA)
        throw IoError(ISOMEND_IO_ERR_INVALID_ARGUMENT, "invalid channel " + std::to_string(o.channel));
    if (o.step == 0) throw IoError(ISOMEND_IO_ERR_INVALID_ARGUMENT, "step must not be 0");
    if (o.count < 0) throw IoError(ISOMEND_IO_ERR_INVALID_ARGUMENT, "count must be >= 0");
    copy_positions(s);
    init_images();

    std::vector<std::string> files;
    bool raw_requested = o.raw_dims[0] > 0 || o.raw_dims[1] > 0 || o.raw_dims[2] > 0;
    DicomFiles dicom_files;
    bool is_dicom = false;
    if (!raw_requested && count == 1 && !is_directory(paths[0]) && is_nifti_path(paths[0])) {
        open_nifti(s, paths[0]);
        return;
    }
    if (s->axes == ISOMEND_IO_AXES_RAS)
        throw IoError(ISOMEND_IO_ERR_INVALID_ARGUMENT,
                      std::string(paths[0]) +
                          ": RAS axes apply to NIfTI volumes only (a DICOM series is in patient LPS "
                          "coordinates; --grid-axes keeps its own frame)");
    if (!raw_requested) {
        std::string p0 = paths[0];
        if (count >= 2) {
            if (is_regular_file(p0) && is_dicom_file(p0)) {
                is_dicom = true;
                dicom_files.label = p0;
                dicom_files.files.assign(paths, paths + count);
                dicom_files.explicit_list = true;
            }
        } else if (is_directory(p0)) {
            is_dicom = dicom_folder_files(p0, false, dicom_files);
            if (!is_dicom) {
                try {
                    files = list_folder(p0);
                } catch (const IoError &e) {
                    // no images either: an export's root with the series in subfolders?
                    if (e.status != ISOMEND_IO_ERR_NOT_FOUND || !dicom_folder_files(p0, true, dicom_files)) throw;
                    is_dicom = true;
                }
            }
        } else if (is_regular_file(p0) && !isomend_fileio_is_nrrd_path(p0.c_str()) && is_dicom_file(p0)) {
            is_dicom = true;
            if (!dicomdir_files(p0, dicom_files)) {
                dicom_files.label = p0;
                dicom_files.files = {p0};
            }
        }
    }
    if (is_dicom) {
        open_dicom(s, dicom_files);
        return;
    }
    if (!files.empty()) {
        s->kind = ISOMEND_IO_KIND_FOLDER;
    } else if (count >= 2) {
        s->kind = ISOMEND_IO_KIND_LIST;
        files.assign(paths, paths + count);
        for (const auto &f : files)
            if (!is_regular_file(f))
                throw IoError(ISOMEND_IO_ERR_NOT_FOUND,
                              f + (is_directory(f) ? ": is a folder, not an image file" : ": file not found"));
    } else {
        std::string p = paths[0];
        if (is_directory(p)) {
            s->kind = ISOMEND_IO_KIND_FOLDER;
            files = list_folder(p);
        } else if (is_regular_file(p)) {
            if (isomend_fileio_is_nrrd_path(p.c_str()) || raw_requested) {
                open_file_volume(s, p, !raw_requested);
                apply_overrides(s);
                apply_positions(s);
                s->opened = true;
                return;
            }
            int pages = count_subimages(p);
            if (pages < 2)
                throw IoError(ISOMEND_IO_ERR_TOO_FEW_SLICES,
                              p + ": a single 2D image; a stack needs at least two slices (give a "
                                  "folder, a glob, a pattern, a list or a multi-page file)");
            s->kind = ISOMEND_IO_KIND_MULTIPAGE;
            for (int k = 0; k < pages; k++) s->slices.push_back(Slice{p, k, true});
            locate_tiff_pages(s->slices); // TIFF: open each page directly
        } else if (is_printf_pattern(p)) {
            s->kind = ISOMEND_IO_KIND_PATTERN;
            files = expand_pattern(p, o.first, o.count, o.step);
        } else if (has_glob_chars(p)) {
            s->kind = ISOMEND_IO_KIND_GLOB;
            files = expand_glob(p);
        } else {
            throw IoError(ISOMEND_IO_ERR_NOT_FOUND, p + ": no such file or folder");
        }
    }
    if (!raw_requested && (s->kind == ISOMEND_IO_KIND_GLOB || s->kind == ISOMEND_IO_KIND_PATTERN) &&
        !files.empty() && is_dicom_file(files[0])) {
        // 'ct/*.dcm', 'IM%04d': the files it names, as a list of DICOM files
        dicom_files.label = paths[0];
        dicom_files.files = files;
        dicom_files.explicit_list = true;
        open_dicom(s, dicom_files);
        return;
    }
    if (raw_requested && s->kind != ISOMEND_IO_KIND_MULTIPAGE && !files.empty())
        throw IoError(ISOMEND_IO_ERR_INVALID_ARGUMENT, "raw dimensions apply to a single raw file only");
    for (const auto &f : files) s->slices.push_back(Slice{f, 0, false});
    if (s->slices.size() < 2)
        throw IoError(ISOMEND_IO_ERR_TOO_FEW_SLICES,
                      (s->slices.empty() ? std::string(paths[0]) : s->slices[0].path) +
                          ": only " + std::to_string(s->slices.size()) +
                          " slice found; a stack needs at least two");
    isomend_io_progress_fn fn = o.progress;
    void *user = o.progress_user;
    scan_stack(s->slices, o.channel, o.threads, s->info, [&](double f) {
        if (fn && fn(user, ISOMEND_IO_STAGE_OPEN, f))
            throw IoError(ISOMEND_IO_ERR_CANCELLED, "cancelled while opening slices");
    });
    apply_overrides(s);
    apply_positions(s);
    s->opened = true;
}

struct ExtractProgress {
    isomend_io_progress_fn fn;
    void *user;
};

int extract_progress(void *user, double f) {
    auto *p = (ExtractProgress *)user;
    return p->fn(p->user, ISOMEND_IO_STAGE_EXTRACT, f);
}

} // namespace

// ======================================================================= C API

extern "C" {

ISOMEND_IO_API const char *isomend_io_status_string(isomend_io_status status) {
    switch (status) {
    case ISOMEND_IO_OK: return "success";
    case ISOMEND_IO_ERR_INVALID_ARGUMENT: return "invalid argument";
    case ISOMEND_IO_ERR_NOT_FOUND: return "not found";
    case ISOMEND_IO_ERR_UNREADABLE: return "unreadable or unknown file";
    case ISOMEND_IO_ERR_CORRUPT: return "corrupt or truncated data";
    case ISOMEND_IO_ERR_MISMATCH: return "slice differs from the first slice";
    case ISOMEND_IO_ERR_UNSUPPORTED: return "unsupported image";
    case ISOMEND_IO_ERR_TOO_FEW_SLICES: return "fewer than two slices";
    case ISOMEND_IO_ERR_TOO_LARGE: return "volume larger than the memory available";
    case ISOMEND_IO_ERR_OUT_OF_MEMORY: return "out of memory";
    case ISOMEND_IO_ERR_CANCELLED: return "cancelled";
    case ISOMEND_IO_ERR_EXTRACT: return "extraction failed";
    case ISOMEND_IO_ERR_INTERNAL: return "internal error";
    case ISOMEND_IO_ERR_SERIES: return "several DICOM series: choose one";
    }
    return "unknown status";
}

ISOMEND_IO_API const char *isomend_io_version(void) { return isomend_version(); }

ISOMEND_IO_API const char *isomend_io_image_libraries(void) {
    static const std::string libraries = [] {
        try {
            return image_backend();
        } catch (...) {
            return std::string("unknown");
        }
    }();
    return libraries.c_str();
}

ISOMEND_IO_API void isomend_io_options_init(isomend_io_options *opts) {
    if (!opts) return;
    std::memset(opts, 0, sizeof *opts);
    opts->first = 0;
    opts->count = 0;
    opts->step = 1;
    opts->channel = ISOMEND_IO_CHANNEL_AUTO;
    opts->raw_type = ISOMEND_U8;
}

ISOMEND_IO_API isomend_io_status isomend_io_create(isomend_io_source **out) {
    if (!out) return ISOMEND_IO_ERR_INVALID_ARGUMENT;
    *out = nullptr;
    try {
        *out = new isomend_io_source();
        isomend_io_options_init(&(*out)->opts);
        return ISOMEND_IO_OK;
    } catch (...) {
        return ISOMEND_IO_ERR_OUT_OF_MEMORY;
    }
}

ISOMEND_IO_API void isomend_io_destroy(isomend_io_source *src) { delete src; }

ISOMEND_IO_API const char *isomend_io_message(const isomend_io_source *src) {
    return src ? src->message.c_str() : "";
}

ISOMEND_IO_API isomend_io_status isomend_io_open(isomend_io_source *src, const char *const *paths,
                                                 size_t path_count, const isomend_io_options *opts) {
    if (!src) return ISOMEND_IO_ERR_INVALID_ARGUMENT;
    isomend_io_status st = guard(src, [&] { do_open(src, paths, path_count, opts); });
    if (st != ISOMEND_IO_OK) {
        src->opened = false;
        src->slices.clear();
    }
    return st;
}

ISOMEND_IO_API isomend_io_status isomend_io_dims(const isomend_io_source *src, int64_t dims[3]) {
    if (!src || !dims || !src->opened) return ISOMEND_IO_ERR_INVALID_ARGUMENT;
    for (int a = 0; a < 3; a++) dims[a] = dim(src, a);
    return ISOMEND_IO_OK;
}

ISOMEND_IO_API isomend_io_status isomend_io_type(const isomend_io_source *src, isomend_type *type) {
    if (!src || !type || !src->opened) return ISOMEND_IO_ERR_INVALID_ARGUMENT;
    *type = src_type(src);
    return ISOMEND_IO_OK;
}

ISOMEND_IO_API uint64_t isomend_io_volume_bytes(const isomend_io_source *src) {
    return src && src->opened ? volume_bytes(src) : 0;
}

ISOMEND_IO_API uint64_t isomend_io_slice_bytes(const isomend_io_source *src) {
    return src && src->opened ? slice_bytes(src) : 0;
}

ISOMEND_IO_API const char *isomend_io_spacing_source_name(int source) {
    switch (source) {
    case ISOMEND_IO_SPACING_DEFAULT: return "default";
    case ISOMEND_IO_SPACING_OPTION: return "option";
    case ISOMEND_IO_SPACING_TIFF: return "tiff";
    case ISOMEND_IO_SPACING_IMAGEJ: return "imagej";
    case ISOMEND_IO_SPACING_HEADER: return "header";
    case ISOMEND_IO_SPACING_DICOM: return "dicom";
    case ISOMEND_IO_SPACING_POSITIONS: return "positions";
    default: return nullptr;
    }
}

ISOMEND_IO_API isomend_io_status isomend_io_spacing(const isomend_io_source *src, double spacing[3],
                                                    int sources[3]) {
    if (!src || !spacing || !src->opened) return ISOMEND_IO_ERR_INVALID_ARGUMENT;
    for (int a = 0; a < 3; a++) {
        spacing[a] = src->is_file_volume ? src->file_info.spacing[a] : src->info.spacing[a];
        if (sources) sources[a] = src->info.spacing_source[a];
    }
    return ISOMEND_IO_OK;
}

ISOMEND_IO_API isomend_io_status isomend_io_origin(const isomend_io_source *src, double origin[3]) {
    if (!src || !origin || !src->opened) return ISOMEND_IO_ERR_INVALID_ARGUMENT;
    for (int a = 0; a < 3; a++) origin[a] = src->origin[a];
    return ISOMEND_IO_OK;
}

ISOMEND_IO_API const char *isomend_io_kind_name(int kind) {
    switch (kind) {
    case ISOMEND_IO_KIND_FOLDER: return "folder";
    case ISOMEND_IO_KIND_GLOB: return "glob";
    case ISOMEND_IO_KIND_PATTERN: return "pattern";
    case ISOMEND_IO_KIND_LIST: return "list";
    case ISOMEND_IO_KIND_MULTIPAGE: return "multipage";
    case ISOMEND_IO_KIND_RAW: return "raw";
    case ISOMEND_IO_KIND_NRRD: return "nrrd";
    case ISOMEND_IO_KIND_DICOM: return "dicom";
    case ISOMEND_IO_KIND_NIFTI: return "nifti";
    default: return nullptr;
    }
}

ISOMEND_IO_API int isomend_io_source_kind(const isomend_io_source *src) {
    return src && src->opened ? src->kind : -1;
}

ISOMEND_IO_API const char *isomend_io_format(const isomend_io_source *src) {
    return src && src->opened ? src->info.format.c_str() : "";
}

ISOMEND_IO_API const char *isomend_io_slice_path(const isomend_io_source *src, int64_t k) {
    if (!src || !src->opened || k < 0 || k >= dim(src, 2)) return nullptr;
    if (src->is_file_volume) return src->file_info.path;
    return src->slices[(size_t)k].path.c_str();
}

ISOMEND_IO_API isomend_io_status isomend_io_geometry_info(const isomend_io_source *src,
                                                          isomend_io_geometry *out) {
    if (!src || !out || !src->opened || src->in_job) return ISOMEND_IO_ERR_INVALID_ARGUMENT;
    const SliceGeometry &g = src->geometry;
    isomend_io_geometry v;
    std::memset(&v, 0, sizeof v);
    v.size = std::min(out->size, sizeof v);
    v.uniform = g.origins.empty() ? 1 : 0;
    v.gap_median = g.gap_median;
    v.gap_min = g.gap_min;
    v.gap_max = g.gap_max;
    v.tilt_degrees = g.tilt_degrees;
    v.max_offset = g.max_offset;
    v.long_gaps = g.long_gaps;
    v.uneven_gaps = g.uneven_gaps;
    v.warning = g.warning.c_str();
    std::memcpy(out, &v, v.size);
    return ISOMEND_IO_OK;
}

ISOMEND_IO_API const double *isomend_io_slice_origins(const isomend_io_source *src) {
    if (!src || !src->opened || src->in_job || src->geometry.origins.empty()) return nullptr;
    return src->geometry.origins.data();
}

ISOMEND_IO_API isomend_io_status isomend_io_read(isomend_io_source *src, void *buffer, size_t buffer_size) {
    if (!src) return ISOMEND_IO_ERR_INVALID_ARGUMENT;
    return guard(src, [&] {
        require_open(src);
        do_read(src, buffer, buffer_size, src->opts.progress, src->opts.progress_user);
    });
}

ISOMEND_IO_API isomend_io_status isomend_io_read_slice(isomend_io_source *src, int64_t k, void *buffer,
                                                       size_t buffer_size) {
    if (!src) return ISOMEND_IO_ERR_INVALID_ARGUMENT;
    return guard(src, [&] {
        require_open(src);
        if (k < 0 || k >= dim(src, 2))
            throw IoError(ISOMEND_IO_ERR_INVALID_ARGUMENT,
                          "slice " + std::to_string(k) + " out of range 0.." + std::to_string(dim(src, 2) - 1));
        if (!buffer || buffer_size < slice_bytes(src))
            throw IoError(ISOMEND_IO_ERR_INVALID_ARGUMENT,
                          "buffer of " + std::to_string(buffer_size) + " bytes is too small for one slice (" +
                              std::to_string(slice_bytes(src)) + " bytes)");
        if (src->is_file_volume) read_file_slice(src, k, buffer, buffer_size);
        else if (src->nifti) nifti_read_slice(*src->nifti, k, buffer);
        else if (src->dicom) dicom_read_slice(*src->dicom, k, buffer);
        else read_slice(src->slices[(size_t)k], src->info, buffer);
    });
}

ISOMEND_IO_API isomend_io_status isomend_io_load(isomend_io_source *src, isomend_volume *vol, double *seconds) {
    if (!src) return ISOMEND_IO_ERR_INVALID_ARGUMENT;
    return guard(src, [&] { do_load(src, vol, seconds); });
}

ISOMEND_IO_API isomend_io_status isomend_io_analyse(isomend_io_source *src, isomend_io_summary *summary) {
    if (!src) return ISOMEND_IO_ERR_INVALID_ARGUMENT;
    return guard(src, [&] {
        require_open(src);
        if (!summary) throw IoError(ISOMEND_IO_ERR_INVALID_ARGUMENT, "summary is NULL");
        do_analyse(src);
        *summary = src->summary;
    });
}

ISOMEND_IO_API isomend_io_status isomend_io_extract(isomend_io_source *src, const isomend_options *opts,
                                                    int use_suggested_iso, double *iso_used,
                                                    isomend_mesh **out_mesh, isomend_stats *stats) {
    if (out_mesh) *out_mesh = nullptr;
    if (!src) return ISOMEND_IO_ERR_INVALID_ARGUMENT;
    return guard(src, [&] {
        require_open(src);
        if (!out_mesh) throw IoError(ISOMEND_IO_ERR_INVALID_ARGUMENT, "out_mesh is NULL");
        isomend_volume vol;
        do_load(src, &vol, nullptr);
        isomend_options o;
        if (opts) o = *opts;
        else isomend_options_init(&o);
        if (use_suggested_iso) {
            do_analyse(src);
            o.iso = src->summary.suggested_iso;
        }
        ExtractProgress ep{src->opts.progress, src->opts.progress_user};
        if (!o.progress && ep.fn) {
            o.progress = extract_progress;
            o.progress_user = &ep;
        }
        if (iso_used) *iso_used = o.iso;
        isomend_status st = isomend_extract(&vol, &o, out_mesh, stats);
        if (st == ISOMEND_ERR_CANCELLED) throw IoError(ISOMEND_IO_ERR_CANCELLED, "cancelled during extraction");
        if (st != ISOMEND_OK)
            throw IoError(ISOMEND_IO_ERR_EXTRACT,
                          std::string("extraction failed: ") + isomend_status_string(st));
    });
}

// ---------------------------------------------------------------- label maps

namespace {

// The source as messages name it: its file, or its first slice's.
std::string source_name(const isomend_io_source *s) {
    if (s->nifti) return s->nifti->path;
    if (s->is_file_volume) return s->file_info.path;
    return s->slices.empty() ? std::string("the source") : s->slices.front().path;
}

} // namespace

struct isomend_io_label_names {
    label_table table{nullptr, 0, 0, ""};
    ~isomend_io_label_names() { label_table_free(&table); }
};

ISOMEND_IO_API isomend_io_status isomend_io_labels_extract(isomend_io_source *src, const int64_t *labels,
                                                           size_t count, const isomend_options *opts,
                                                           isomend_labels **out) {
    if (out) *out = nullptr;
    if (!src || src->in_job) return ISOMEND_IO_ERR_INVALID_ARGUMENT;
    return guard(src, [&] {
        require_open(src);
        if (!out) throw IoError(ISOMEND_IO_ERR_INVALID_ARGUMENT, "out is NULL");
        if (count && !labels) throw IoError(ISOMEND_IO_ERR_INVALID_ARGUMENT, "labels is NULL");
        isomend_volume loaded, vol;
        do_load(src, &loaded, nullptr);
        if (loaded.slice_origins)
            throw IoError(ISOMEND_IO_ERR_UNSUPPORTED,
                          source_name(src) + ": a label map's slices must be evenly spaced");
        const std::string name = source_name(src);
        void *copy = nullptr;
        char msg[512];
        if (label_samples_integer(&loaded, name.c_str(), &vol, &copy, msg, sizeof msg))
            throw IoError(ISOMEND_IO_ERR_UNSUPPORTED, msg);
        std::unique_ptr<void, void (*)(void *)> keep(copy, free);
        isomend_options o;
        if (opts) o = *opts;
        else isomend_options_init(&o);
        ExtractProgress ep{src->opts.progress, src->opts.progress_user};
        if (!o.progress && ep.fn) {
            o.progress = extract_progress;
            o.progress_user = &ep;
        }
        isomend_labels *res = nullptr;
        isomend_status st = isomend_labels_extract(&vol, labels, count, &o, &res);
        if (st == ISOMEND_ERR_CANCELLED) throw IoError(ISOMEND_IO_ERR_CANCELLED, "cancelled during extraction");
        if (st != ISOMEND_OK)
            throw IoError(ISOMEND_IO_ERR_EXTRACT,
                          std::string("label extraction failed: ") + isomend_status_string(st));
        std::unique_ptr<isomend_labels, void (*)(isomend_labels *)> result(res, isomend_labels_destroy);
        const size_t n = isomend_labels_count(res);
        if (n == 0)
            throw IoError(ISOMEND_IO_ERR_INVALID_ARGUMENT, name + " has no label but the background 0");
        for (size_t q = 0; q < n; q++)
            if (isomend_labels_voxels(res, q) == 0)
                throw IoError(ISOMEND_IO_ERR_INVALID_ARGUMENT,
                              "label " + std::to_string(isomend_labels_value(res, q)) + " is not in " + name);
        *out = result.release();
    });
}

ISOMEND_IO_API isomend_io_status isomend_io_label_names_read(isomend_io_source *src, const char *path,
                                                             isomend_io_label_names **out) {
    if (out) *out = nullptr;
    if (!src || src->in_job) return ISOMEND_IO_ERR_INVALID_ARGUMENT;
    return guard(src, [&] {
        if (!out) throw IoError(ISOMEND_IO_ERR_INVALID_ARGUMENT, "out is NULL");
        std::unique_ptr<isomend_io_label_names> names(new isomend_io_label_names);
        char msg[512];
        if (path) {
            if (label_table_read(path, &names->table, msg, sizeof msg)) {
                // io/common names the command line's option; here the file is the subject
                const char *opt = "--label-table ";
                throw IoError(ISOMEND_IO_ERR_UNREADABLE,
                              std::strncmp(msg, opt, std::strlen(opt)) ? msg : msg + std::strlen(opt));
            }
        } else {
            require_open(src);
            if (src->is_file_volume && src->kind == ISOMEND_IO_KIND_NRRD &&
                label_table_from_nrrd(src->file_info.path, &names->table, msg, sizeof msg) < 0)
                throw IoError(ISOMEND_IO_ERR_CORRUPT, msg);
        }
        *out = names.release();
    });
}

ISOMEND_IO_API const char *isomend_io_label_names_from(const isomend_io_label_names *names) {
    return names && names->table.count ? names->table.source : "";
}

ISOMEND_IO_API int isomend_io_label_name(const isomend_io_label_names *names, int64_t value, char *name,
                                         size_t name_size, uint8_t rgb[3]) {
    char buf[LABEL_NAME_MAX];
    uint8_t c[3];
    const int known = label_describe(names ? &names->table : nullptr, value, buf, sizeof buf, c);
    if (name && name_size) snprintf(name, name_size, "%s", buf);
    if (rgb) memcpy(rgb, c, 3);
    return known;
}

ISOMEND_IO_API void isomend_io_label_names_destroy(isomend_io_label_names *names) { delete names; }

// ---------------------------------------------------------------- DICOM

ISOMEND_IO_API isomend_io_status isomend_io_set_series(isomend_io_source *src, const char *series) {
    if (!src || src->in_job) return ISOMEND_IO_ERR_INVALID_ARGUMENT;
    return guard(src, [&] {
        if (src->open_attempted)
            throw IoError(ISOMEND_IO_ERR_INVALID_ARGUMENT, "the series is chosen before isomend_io_open");
        src->series_choice = series ? series : "";
    });
}

ISOMEND_IO_API isomend_io_status isomend_io_set_axes(isomend_io_source *src, int axes) {
    if (!src || src->in_job) return ISOMEND_IO_ERR_INVALID_ARGUMENT;
    return guard(src, [&] {
        if (src->open_attempted)
            throw IoError(ISOMEND_IO_ERR_INVALID_ARGUMENT, "the axes are chosen before isomend_io_open");
        if (axes != ISOMEND_IO_AXES_PATIENT && axes != ISOMEND_IO_AXES_GRID && axes != ISOMEND_IO_AXES_RAS)
            throw IoError(ISOMEND_IO_ERR_INVALID_ARGUMENT, "invalid axes " + std::to_string(axes));
        src->axes = axes;
    });
}

ISOMEND_IO_API int64_t isomend_io_series_count(const isomend_io_source *src) {
    return src && !src->in_job ? (int64_t)src->series_found.size() : 0;
}

ISOMEND_IO_API isomend_io_status isomend_io_series_get(const isomend_io_source *src, int64_t index,
                                                       isomend_io_series *out) {
    if (!src || !out || src->in_job || index < 0 || index >= (int64_t)src->series_found.size())
        return ISOMEND_IO_ERR_INVALID_ARGUMENT;
    const DicomSeriesEntry &e = src->series_found[(size_t)index];
    isomend_io_series v;
    std::memset(&v, 0, sizeof v);
    v.size = std::min(out->size, sizeof v);
    v.uid = e.uid.c_str();
    v.description = e.description.c_str();
    v.modality = e.modality.c_str();
    v.number = e.number;
    v.files = e.files;
    v.images = e.images;
    v.columns = e.columns;
    v.rows = e.rows;
    std::memcpy(out, &v, v.size);
    return ISOMEND_IO_OK;
}

ISOMEND_IO_API int64_t isomend_io_series_chosen(const isomend_io_source *src) {
    return src && src->opened && src->dicom ? src->dicom->chosen : -1;
}

ISOMEND_IO_API isomend_io_status isomend_io_dicom_info(const isomend_io_source *src, isomend_io_dicom *out) {
    if (!src || !out || !src->opened) return ISOMEND_IO_ERR_INVALID_ARGUMENT;
    if (!src->dicom) return ISOMEND_IO_ERR_UNSUPPORTED;
    const DicomSeries &d = *src->dicom;
    isomend_io_dicom v;
    std::memset(&v, 0, sizeof v);
    v.size = std::min(out->size, sizeof v);
    v.modality = d.modality.c_str();
    v.series_uid = d.uid.c_str();
    v.description = d.description.c_str();
    v.transfer_syntax = d.ts_uid.c_str();
    v.transfer_syntax_name = d.ts_name.c_str();
    v.photometric = d.photometric.c_str();
    v.bits_stored = d.bits_stored;
    v.pixel_signed = d.pixel_signed ? 1 : 0;
    v.rescaled = d.rescaled ? 1 : 0;
    v.hounsfield = d.hounsfield ? 1 : 0;
    v.rescale_slope = d.frames.empty() ? 1.0 : d.frames[0].slope;
    v.rescale_intercept = d.frames.empty() ? 0.0 : d.frames[0].intercept;
    std::memcpy(v.orientation, d.orientation, sizeof v.orientation);
    std::memcpy(v.normal, d.normal, sizeof v.normal);
    std::memcpy(v.position, d.position, sizeof v.position);
    v.files = d.files;
    v.multiframe = d.multiframe ? 1 : 0;
    v.non_image = d.non_image;
    v.non_dicom = d.non_dicom;
    v.other_series = d.other_series;
    v.axes = d.axes;
    std::memcpy(out, &v, v.size);
    return ISOMEND_IO_OK;
}

ISOMEND_IO_API isomend_io_status isomend_io_world_transform(const isomend_io_source *src, double affine[12],
                                                            int *identity) {
    if (!src || !affine || !src->opened) return ISOMEND_IO_ERR_INVALID_ARGUMENT;
    const double *a = src->nifti ? src->nifti->affine : src->dicom ? src->dicom->affine : nullptr;
    bool id = src->nifti ? src->nifti->identity : !src->dicom || src->dicom->identity;
    for (int i = 0; i < 12; i++) affine[i] = id ? (i % 5 == 0 ? 1.0 : 0.0) : a[i];
    if (identity) *identity = id ? 1 : 0;
    return ISOMEND_IO_OK;
}

ISOMEND_IO_API isomend_io_status isomend_io_nifti_info(const isomend_io_source *src, isomend_io_nifti *out) {
    if (!src || !out || !src->opened || src->in_job) return ISOMEND_IO_ERR_INVALID_ARGUMENT;
    if (!src->nifti) return ISOMEND_IO_ERR_UNSUPPORTED;
    const NiftiVolume &n = *src->nifti;
    isomend_io_nifti v;
    std::memset(&v, 0, sizeof v);
    v.size = std::min(out->size, sizeof v);
    v.version = n.version;
    v.two_files = n.two_files ? 1 : 0;
    v.gzip = n.gzip ? 1 : 0;
    v.header_path = n.header_path.c_str();
    v.image_path = n.image_path.c_str();
    v.datatype = n.datatype_name.c_str();
    v.scaled = n.scaled ? 1 : 0;
    v.scl_slope = n.slope;
    v.scl_inter = n.inter;
    v.sform_code = n.sform_code;
    v.qform_code = n.qform_code;
    v.transform = n.transform.c_str();
    std::memcpy(v.file_affine, n.file_affine, sizeof v.file_affine);
    v.axes = n.axes;
    std::memcpy(out, &v, v.size);
    return ISOMEND_IO_OK;
}

ISOMEND_IO_API const char *isomend_io_level_name(int level) {
    switch (level) {
    case ISOMEND_IO_LEVEL_OTSU: return "otsu";
    case ISOMEND_IO_LEVEL_BONE: return "bone";
    case ISOMEND_IO_LEVEL_SKIN: return "skin";
    default: return nullptr;
    }
}

ISOMEND_IO_API isomend_io_status isomend_io_level_value(isomend_io_source *src, int level, double *value) {
    if (!src) return ISOMEND_IO_ERR_INVALID_ARGUMENT;
    return guard(src, [&] {
        require_open(src);
        if (!value) throw IoError(ISOMEND_IO_ERR_INVALID_ARGUMENT, "value is NULL");
        if (level == ISOMEND_IO_LEVEL_OTSU) {
            do_analyse(src);
            *value = src->otsu;
            return;
        }
        if (level != ISOMEND_IO_LEVEL_BONE && level != ISOMEND_IO_LEVEL_SKIN)
            throw IoError(ISOMEND_IO_ERR_INVALID_ARGUMENT, "invalid level " + std::to_string(level));
        if (!src->dicom || !src->dicom->hounsfield) {
            std::string what = src->dicom ? "a DICOM series of modality " +
                                                (src->dicom->modality.empty() ? std::string("(none)") : src->dicom->modality)
                                          : std::string("not a DICOM series");
            throw IoError(ISOMEND_IO_ERR_UNSUPPORTED,
                          std::string("the ") + isomend_io_level_name(level) +
                              " level is for CT in Hounsfield units; the source is " + what +
                              " (give the level as a number)");
        }
        *value = level == ISOMEND_IO_LEVEL_BONE ? kBoneHU : kSkinHU;
    });
}

ISOMEND_IO_API int isomend_io_suggested_level(const isomend_io_source *src) {
    if (!src || !src->opened) return -1;
    return src->dicom && src->dicom->hounsfield ? ISOMEND_IO_LEVEL_BONE : ISOMEND_IO_LEVEL_OTSU;
}

// ---------------------------------------------------------------- jobs

struct isomend_io_job {
    isomend_io_source *src = nullptr;
    std::vector<std::string> paths;
    isomend_io_options io_opts{};
    std::vector<double> positions; // io_opts.slice_positions, copied
    isomend_options opts{};
    int use_suggested_iso = 0;
    // written by the job's thread, read by poll()
    std::atomic<int> stage{ISOMEND_IO_STAGE_OPEN};
    std::atomic<double> fraction{0.0};
    std::atomic<bool> cancel{false};
    std::atomic<bool> ended{false};
    // the outcome, read after the join
    isomend_io_status status = ISOMEND_IO_OK;
    double iso_used = 0.0;
    isomend_mesh *mesh = nullptr;
    isomend_stats stats{};
    std::thread thread;
};

namespace {

// The only progress callback a job's work sees: records, and answers the
// cancel request.  Runs on the job's thread (and nowhere else).
int job_progress(void *user, int stage, double fraction) {
    auto *job = (isomend_io_job *)user;
    job->stage.store(stage, std::memory_order_relaxed);
    job->fraction.store(fraction, std::memory_order_relaxed);
    return job->cancel.load(std::memory_order_relaxed) ? 1 : 0;
}

void job_run(isomend_io_job *job) {
    std::vector<const char *> paths;
    for (const auto &p : job->paths) paths.push_back(p.c_str());
    job->status = isomend_io_open(job->src, paths.data(), paths.size(), &job->io_opts);
    if (job->status == ISOMEND_IO_OK) {
        job->stage.store(ISOMEND_IO_STAGE_READ, std::memory_order_relaxed);
        job->fraction.store(0.0, std::memory_order_relaxed);
        job->status = isomend_io_extract(job->src, &job->opts, job->use_suggested_iso, &job->iso_used,
                                         &job->mesh, &job->stats);
    }
    job->ended.store(true, std::memory_order_release);
}

} // namespace

ISOMEND_IO_API isomend_io_status isomend_io_job_start(isomend_io_source *src, const char *const *paths,
                                                      size_t path_count, const isomend_io_options *io_opts,
                                                      const isomend_options *opts, int use_suggested_iso,
                                                      isomend_io_job **out_job) {
    if (out_job) *out_job = nullptr;
    // A handle a job has is the job's: not even its message is written here.
    if (!src || src->in_job) return ISOMEND_IO_ERR_INVALID_ARGUMENT;
    std::unique_ptr<isomend_io_job> job;
    isomend_io_status st = guard(src, [&] {
        if (!out_job) throw IoError(ISOMEND_IO_ERR_INVALID_ARGUMENT, "out_job is NULL");
        if (src->open_attempted)
            throw IoError(ISOMEND_IO_ERR_INVALID_ARGUMENT, "a job needs a source that has not been opened");
        if ((io_opts && io_opts->progress) || (opts && opts->progress))
            throw IoError(ISOMEND_IO_ERR_INVALID_ARGUMENT,
                          "a job calls no progress callback (poll it with isomend_io_job_poll)");
        if (!paths && path_count) throw IoError(ISOMEND_IO_ERR_INVALID_ARGUMENT, "paths is NULL");
        job.reset(new isomend_io_job());
        job->src = src;
        for (size_t i = 0; i < path_count; i++) {
            if (!paths[i])
                throw IoError(ISOMEND_IO_ERR_INVALID_ARGUMENT, "path " + std::to_string(i) + " is NULL");
            job->paths.emplace_back(paths[i]);
        }
        if (io_opts) job->io_opts = *io_opts;
        else isomend_io_options_init(&job->io_opts);
        if (job->io_opts.slice_positions && job->io_opts.slice_position_count) {
            const double *p = job->io_opts.slice_positions;
            job->positions.assign(p, p + job->io_opts.slice_position_count);
            job->io_opts.slice_positions = job->positions.data();
        }
        job->io_opts.progress = job_progress;
        job->io_opts.progress_user = job.get();
        if (opts) job->opts = *opts;
        else isomend_options_init(&job->opts);
        job->use_suggested_iso = use_suggested_iso;
        try {
            src->in_job = true;
            job->thread = std::thread(job_run, job.get());
        } catch (const std::system_error &e) {
            src->in_job = false;
            throw IoError(ISOMEND_IO_ERR_INTERNAL, std::string("cannot start the job's thread: ") + e.what());
        }
    });
    if (st == ISOMEND_IO_OK) *out_job = job.release();
    return st;
}

ISOMEND_IO_API int isomend_io_job_poll(const isomend_io_job *job, int *stage, double *fraction) {
    if (!job) return 1;
    if (stage) *stage = job->stage.load(std::memory_order_relaxed);
    if (fraction) *fraction = job->fraction.load(std::memory_order_relaxed);
    return job->ended.load(std::memory_order_acquire) ? 1 : 0;
}

ISOMEND_IO_API void isomend_io_job_cancel(isomend_io_job *job) {
    if (job) job->cancel.store(true, std::memory_order_relaxed);
}

ISOMEND_IO_API isomend_io_status isomend_io_job_finish(isomend_io_job *job, double *iso_used,
                                                       isomend_mesh **out_mesh, isomend_stats *stats) {
    if (out_mesh) *out_mesh = nullptr;
    if (!job) return ISOMEND_IO_ERR_INVALID_ARGUMENT;
    std::unique_ptr<isomend_io_job> owned(job);
    if (job->thread.joinable()) job->thread.join();
    // The source kept the job's callback for later reads: it must not outlive the job.
    job->src->opts.progress = nullptr;
    job->src->opts.progress_user = nullptr;
    job->src->in_job = false;
    if (iso_used) *iso_used = job->iso_used;
    if (stats) *stats = job->stats;
    if (out_mesh) *out_mesh = job->mesh;
    else isomend_mesh_destroy(job->mesh);
    return job->status;
}

} // extern "C"
