// stack.cpp - opening, validating and reading slice stacks.
//
// Every slice's header is checked against the first slice's before anything
// is read, so that a stack that cannot be one fails at once with a message
// naming the slice: the whole data window (an offset window passes a
// width/height test), the channel count, the channel's type, the stored bit
// depth and the depth (a 3D image is not a slice).  Slices are then read by
// worker threads, each decode checked, while the calling thread reports
// progress.
//
// The image library is reached only through image.hpp: OpenImageIO or
// libtiff/OpenEXR/libpng, whichever this build links.  Both deliver the
// stored sample values (the quirks of each are handled behind that
// interface), so this file converts nothing but uint32 (to double, exact)
// and RGB to luminance when asked.
#include "image.hpp"
#include "parallel_slices.hpp"

#include <algorithm>
#include <chrono>
#include <condition_variable>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <memory>
#include <mutex>
#include <system_error>
#include <thread>

namespace isomend_io {

size_t StackInfo::sample_size() const { return isomend_type_size(type); }

std::string slice_name(const Slice &s) {
    if (!s.multipage) return s.path;
    return s.path + " (page " + std::to_string(s.subimage + 1) + ")";
}

const char *sample_name(Sample t) {
    switch (t) {
    case Sample::U8: return "uint8";
    case Sample::I8: return "int8";
    case Sample::U16: return "uint16";
    case Sample::I16: return "int16";
    case Sample::U32: return "uint32";
    case Sample::I32: return "int32";
    case Sample::HALF: return "half";
    case Sample::FLOAT: return "float";
    case Sample::DOUBLE: return "double";
    default: return "unknown";
    }
}

size_t delivered_size(Sample t) {
    switch (t) {
    case Sample::U8:
    case Sample::I8: return 1;
    case Sample::U16:
    case Sample::I16: return 2;
    case Sample::DOUBLE: return 8;
    case Sample::OTHER: return 0;
    default: return 4; // u32, i32, float, half (delivered as float)
    }
}

int ImageHeader::channel_index(const std::string &name) const {
    for (size_t c = 0; c < channel_names.size(); c++)
        if (channel_names[c] == name) return (int)c;
    return -1;
}

static bool map_type(Sample st, isomend_type *t, bool *u32_to_f64) {
    *u32_to_f64 = false;
    switch (st) {
    case Sample::U8: *t = ISOMEND_U8; return true;
    case Sample::I8: *t = ISOMEND_I8; return true;
    case Sample::U16: *t = ISOMEND_U16; return true;
    case Sample::I16: *t = ISOMEND_I16; return true;
    case Sample::I32: *t = ISOMEND_I32; return true;
    case Sample::U32: *t = ISOMEND_F64; *u32_to_f64 = true; return true;
    case Sample::HALF: *t = ISOMEND_F32; return true;
    case Sample::FLOAT: *t = ISOMEND_F32; return true;
    case Sample::DOUBLE: *t = ISOMEND_F64; return true;
    default: return false;
    }
}

static std::string size_text(const ImageHeader &h) {
    std::string t = std::to_string(h.width) + "x" + std::to_string(h.height);
    if (h.x != 0 || h.y != 0) t += " at (" + std::to_string(h.x) + "," + std::to_string(h.y) + ")";
    return t;
}

static std::string info_size_text(const StackInfo &i) {
    std::string t = std::to_string(i.width) + "x" + std::to_string(i.height);
    if (i.xorigin != 0 || i.yorigin != 0)
        t += " at (" + std::to_string(i.xorigin) + "," + std::to_string(i.yorigin) + ")";
    return t;
}

static std::string channel_names(const ImageHeader &h) {
    std::string t;
    for (int c = 0; c < h.nchannels(); c++) {
        if (c) t += ",";
        t += c < (int)h.channel_names.size() && !h.channel_names[c].empty() ? h.channel_names[c]
                                                                             : std::to_string(c);
    }
    return t;
}

// Spacing from the first slice's metadata.
//   ImageJ: ImageDescription "ImageJ=...\nspacing=Z\nunit=U"; XResolution and
//     YResolution are pixels per unit U -> x, y spacing = 1/resolution.
//   TIFF: XResolution/YResolution with ResolutionUnit inch or cm -> mm.  72 and
//     96 pixels per inch are the defaults image programs write when nothing is
//     known (screen resolutions), so they are treated as "no information".
// Resolution tags are floats (~7 digits): 1/1.3333334f is 0.74999996.
// Rounding the spacing to 6 significant digits restores the decimal value
// that was written (0.75) without inventing precision.
static double round_significant(double v) {
    if (!(v > 0) || !std::isfinite(v)) return v;
    double scale = std::pow(10.0, 5 - (int)std::floor(std::log10(v)));
    return std::round(v * scale) / scale;
}

static void spacing_from_metadata(const ImageHeader &h, StackInfo &info) {
    const std::string &desc = h.description;
    bool imagej = desc.rfind("ImageJ=", 0) == 0;
    float xres = h.xres, yres = h.yres;
    std::string unit = h.resolution_unit;
    for (char &c : unit) c = (char)std::tolower((unsigned char)c);
    if (imagej) {
        size_t p = desc.find("\nspacing=");
        if (p != std::string::npos) {
            double z = std::strtod(desc.c_str() + p + 9, nullptr);
            if (std::isfinite(z) && z > 0) {
                info.spacing[2] = z;
                info.spacing_source[2] = ISOMEND_IO_SPACING_IMAGEJ;
            }
        }
        if (xres > 0 && yres > 0 && std::isfinite(xres) && std::isfinite(yres) &&
            !(xres == 1 && yres == 1 && info.spacing_source[2] == 0)) {
            info.spacing[0] = round_significant(1.0 / xres);
            info.spacing[1] = round_significant(1.0 / yres);
            info.spacing_source[0] = info.spacing_source[1] = ISOMEND_IO_SPACING_IMAGEJ;
        }
        return;
    }
    double per_unit_mm = 0;
    if (unit == "in" || unit == "inch") per_unit_mm = 25.4;
    else if (unit == "cm") per_unit_mm = 10.0;
    else if (unit == "mm") per_unit_mm = 1.0;
    if (per_unit_mm > 0 && xres > 0 && yres > 0 && std::isfinite(xres) && std::isfinite(yres)) {
        bool screen_default = per_unit_mm == 25.4 && xres == yres && (xres == 72.0f || xres == 96.0f);
        if (!screen_default) {
            info.spacing[0] = round_significant(per_unit_mm / xres);
            info.spacing[1] = round_significant(per_unit_mm / yres);
            info.spacing_source[0] = info.spacing_source[1] = ISOMEND_IO_SPACING_TIFF;
        }
    }
}

// An ImageJ hyperstack stores its pages in channel, slice, frame order: taking
// the pages as slices would interleave channels or time points silently.
static void refuse_imagej_hyperstack(const Slice &s, const ImageHeader &h) {
    const std::string &desc = h.description;
    if (desc.rfind("ImageJ=", 0) != 0) return;
    for (const char *key : {"channels", "frames"}) {
        std::string k = std::string("\n") + key + "=";
        size_t p = desc.find(k);
        if (p == std::string::npos) continue;
        long n = std::strtol(desc.c_str() + p + k.size(), nullptr, 10);
        if (n > 1)
            throw IoError(ISOMEND_IO_ERR_UNSUPPORTED,
                          s.path + ": an ImageJ hyperstack with " + std::to_string(n) + " " + key +
                              "; its pages interleave them (save one " +
                              (key[0] == 'c' ? "channel" : "time point") + " as a stack in ImageJ)");
    }
}

static void describe_first(const Slice &s, const ImageHeader &h, int channel, StackInfo &info) {
    std::string name = slice_name(s);
    if (h.depth > 1)
        throw IoError(ISOMEND_IO_ERR_UNSUPPORTED,
                      name + ": is a 3D image (depth " + std::to_string(h.depth) +
                          "); only 2D slices can be stacked");
    if (h.width < 1 || h.height < 1 || h.nchannels() < 1)
        throw IoError(ISOMEND_IO_ERR_CORRUPT, name + ": empty image");
    if ((uint64_t)h.width * (uint64_t)h.height > (1ull << 50))
        throw IoError(ISOMEND_IO_ERR_UNSUPPORTED,
                      name + ": " + size_text(h) + " pixels is beyond any memory");
    info.width = h.width;
    info.height = h.height;
    info.xorigin = h.x;
    info.yorigin = h.y;
    info.file_channels = h.nchannels();
    info.bits = h.bits;
    info.luma = false;
    if (channel == ISOMEND_IO_CHANNEL_AUTO) {
        if (h.nchannels() != 1)
            throw IoError(ISOMEND_IO_ERR_UNSUPPORTED,
                          name + ": has " + std::to_string(h.nchannels()) + " channels (" +
                              channel_names(h) +
                              "); choose one with --channel N (0-based) or --channel luma");
        info.channel = 0;
    } else if (channel == ISOMEND_IO_CHANNEL_LUMA) {
        if (h.nchannels() < 3)
            throw IoError(ISOMEND_IO_ERR_UNSUPPORTED,
                          name + ": --channel luma needs 3 channels (R,G,B), the image has " +
                              std::to_string(h.nchannels()) + " (" + channel_names(h) + ")");
        int r = h.channel_index("R"), g = h.channel_index("G"), b = h.channel_index("B");
        if (r < 0 || g < 0 || b < 0) {
            r = 0;
            g = 1;
            b = 2;
        }
        info.luma = true;
        info.luma_channels[0] = r;
        info.luma_channels[1] = g;
        info.luma_channels[2] = b;
        info.channel = r;
    } else if (channel >= 0) {
        if (channel >= h.nchannels())
            throw IoError(ISOMEND_IO_ERR_UNSUPPORTED,
                          name + ": no channel " + std::to_string(channel) + "; the image has " +
                              std::to_string(h.nchannels()) + " (" + channel_names(h) + ")");
        info.channel = channel;
    } else {
        throw IoError(ISOMEND_IO_ERR_INVALID_ARGUMENT, "invalid channel option " + std::to_string(channel));
    }
    info.file_type = h.channel_types[(size_t)info.channel];
    if (info.luma) {
        for (int k = 0; k < 3; k++)
            if (h.channel_types[(size_t)info.luma_channels[k]] != info.file_type)
                throw IoError(ISOMEND_IO_ERR_UNSUPPORTED,
                              name + ": --channel luma needs R, G and B of one sample type");
    }
    isomend_type t;
    bool u32 = false;
    if (!map_type(info.file_type, &t, &u32))
        throw IoError(ISOMEND_IO_ERR_UNSUPPORTED,
                      name + ": sample type " + sample_name(info.file_type) +
                          " is not supported (u8, i8, u16, i16, i32, u32, half, float, double are)");
    info.type = info.luma ? ISOMEND_F32 : t;
    info.u32_to_f64 = u32 && !info.luma;
    spacing_from_metadata(h, info);
    if (s.multipage) refuse_imagej_hyperstack(s, h);
}

static void check_against_first(const Slice &s, const ImageHeader &h, const StackInfo &info,
                                const std::string &first_name) {
    std::string name = slice_name(s);
    std::string ref = " differs from the first slice's ";
    std::string tail = " (" + first_name + ")";
    if (h.depth > 1)
        throw IoError(ISOMEND_IO_ERR_UNSUPPORTED,
                      name + ": is a 3D image (depth " + std::to_string(h.depth) +
                          "); only 2D slices can be stacked");
    if (h.width != info.width || h.height != info.height || h.x != info.xorigin ||
        h.y != info.yorigin)
        throw IoError(ISOMEND_IO_ERR_MISMATCH,
                      name + ": size " + size_text(h) + ref + info_size_text(info) + tail);
    if (h.nchannels() != info.file_channels)
        throw IoError(ISOMEND_IO_ERR_MISMATCH,
                      name + ": " + std::to_string(h.nchannels()) + " channels" + ref +
                          std::to_string(info.file_channels) + tail);
    Sample st = h.channel_types[(size_t)info.channel];
    if (st != info.file_type)
        throw IoError(ISOMEND_IO_ERR_MISMATCH,
                      name + ": sample type " + sample_name(st) + ref + sample_name(info.file_type) +
                          tail);
    if (h.bits != info.bits)
        throw IoError(ISOMEND_IO_ERR_MISMATCH,
                      name + ": " + std::to_string(h.bits) + " bits per sample" + ref +
                          std::to_string(info.bits) + tail);
}

// Per-thread state of the header scan: the open file.
struct ScanCursor {
    std::unique_ptr<ImageFile> file;
};

// Opens slice s's header (reusing the cursor's file when it serves s) and
// runs the checks that need the file itself; returns its header.
static ImageHeader scan_header(ScanCursor &c, const Slice &s) {
    if (!c.file || !c.file->serves(s)) {
        c.file.reset();
        c.file = open_image(s);
        if (!s.multipage && c.file->has_subimage(1)) {
            // A multi-page file inside a folder/list would lose its pages silently.
            int pages = count_subimages(s.path);
            throw IoError(ISOMEND_IO_ERR_UNSUPPORTED,
                          s.path + ": has " + std::to_string(pages) +
                              " pages/parts; a stack of files needs one image per file "
                              "(open a multi-page file on its own)");
        }
    }
    return c.file->header(s);
}

// Slice 0 defines the stack on the calling thread; the other headers are
// checked against it by up to `threads` workers, each on a contiguous run of
// slices (pages of one file are then visited in order, which is what a TIFF
// seek is fast at).  The calling thread reports progress; the error of the
// lowest slice index among those checked is rethrown after all workers stop.
void scan_stack(const std::vector<Slice> &slices, int channel, int threads, StackInfo &info,
                const std::function<void(double)> &progress) {
    if (slices.empty()) return;
    const std::string first_name = slice_name(slices[0]);
    {
        ScanCursor c;
        ImageHeader h = scan_header(c, slices[0]);
        describe_first(slices[0], h, channel, info);
        info.format = c.file->format();
    }
    const size_t n = slices.size();
    size_t workers = std::min<size_t>((size_t)reader_threads_for(threads), (n - 1 + 63) / 64); // >= 64 headers each
    if (workers <= 1) {
        ScanCursor c;
        for (size_t k = 1; k < n; k++) {
            ImageHeader h = scan_header(c, slices[k]);
            check_against_first(slices[k], h, info, first_name);
            if (progress && (k & 31) == 31) progress((double)(k + 1) / (double)n);
        }
        return;
    }
    std::atomic<size_t> done{1};
    std::atomic<bool> stop{false};
    std::mutex mu;
    std::condition_variable finished; // the last header checked, or a failure
    auto wake = [&] {
        { std::lock_guard<std::mutex> lock(mu); } // the waiter is waiting or sees the state
        finished.notify_all();
    };
    size_t error_index = SIZE_MAX;
    isomend_io_status error_status = ISOMEND_IO_OK;
    std::string error_message;
    auto fail = [&](size_t k, isomend_io_status st, const std::string &msg) {
        std::lock_guard<std::mutex> lock(mu);
        if (k < error_index) {
            error_index = k;
            error_status = st;
            error_message = msg;
        }
        stop.store(true);
        finished.notify_all(); // under the lock: the waiter cannot miss it
    };
    const size_t per = (n - 1 + workers - 1) / workers;
    auto worker = [&](size_t begin, size_t end) {
        try {
            ScanCursor c;
            for (size_t k = begin; k < end && !stop.load(); k++) {
                try {
                    ImageHeader h = scan_header(c, slices[k]);
                    check_against_first(slices[k], h, info, first_name);
                } catch (const IoError &e) {
                    fail(k, e.status, e.what());
                    return;
                }
                if (done.fetch_add(1) + 1 >= n) wake();
            }
        } catch (const std::bad_alloc &) {
            fail(n, ISOMEND_IO_ERR_OUT_OF_MEMORY, "out of memory while scanning slices");
        } catch (const std::exception &e) {
            fail(n, ISOMEND_IO_ERR_INTERNAL, std::string("internal error while scanning slices: ") + e.what());
        }
    };
    std::vector<std::thread> pool;
    auto join_all = [&] {
        stop.store(true);
        for (auto &t : pool)
            if (t.joinable()) t.join();
    };
    try {
        for (size_t w = 0; w < workers; w++) {
            size_t begin = 1 + w * per, end = std::min(n, begin + per);
            if (begin < end) pool.emplace_back(worker, begin, end);
        }
    } catch (const std::system_error &) {
        join_all();
        throw IoError(ISOMEND_IO_ERR_INTERNAL, "cannot start header scan threads");
    }
    try {
        // Woken when the last header is checked or a worker fails, else every
        // 50 ms for the progress report: no run waits for a polling period.
        for (;;) {
            // at least one report, before any wait: a cancel is always seen
            if (progress) progress((double)done.load() / (double)n); // may throw (cancel)
            std::unique_lock<std::mutex> lock(mu);
            if (finished.wait_for(lock, std::chrono::milliseconds(50),
                                  [&] { return stop.load() || done.load() >= n; }))
                break;
        }
        if (progress) progress((double)done.load() / (double)n);
    } catch (...) {
        join_all();
        throw;
    }
    for (auto &t : pool) t.join();
    if (error_index != SIZE_MAX) throw IoError(error_status, error_message);
}

template <typename T> static double as_double(const void *p, size_t i) {
    return (double)((const T *)p)[i];
}

static double sample_as_double(Sample t, const void *p, size_t i) {
    switch (t) {
    case Sample::U8: return as_double<uint8_t>(p, i);
    case Sample::I8: return as_double<int8_t>(p, i);
    case Sample::U16: return as_double<uint16_t>(p, i);
    case Sample::I16: return as_double<int16_t>(p, i);
    case Sample::I32: return as_double<int32_t>(p, i);
    case Sample::U32: return as_double<uint32_t>(p, i);
    case Sample::DOUBLE: return as_double<double>(p, i);
    default: return as_double<float>(p, i); // float, and half delivered as float
    }
}

void read_slice(const Slice &s, const StackInfo &info, void *out) {
    std::unique_ptr<ImageFile> file = open_image(s);
    ImageHeader h = file->header(s);
    // The file may have changed since isomend_io_open(): check again (cheap).
    check_against_first(s, h, info, "as opened");
    size_t n = (size_t)info.width * (size_t)info.height;
    if (info.luma) {
        size_t nc = (size_t)info.file_channels;
        std::vector<char> tmp(n * nc * delivered_size(info.file_type));
        file->read(s, h, 0, info.file_channels, tmp.data());
        float *o = (float *)out;
        for (size_t i = 0; i < n; i++) {
            double r = sample_as_double(info.file_type, tmp.data(), i * nc + (size_t)info.luma_channels[0]);
            double g = sample_as_double(info.file_type, tmp.data(), i * nc + (size_t)info.luma_channels[1]);
            double b = sample_as_double(info.file_type, tmp.data(), i * nc + (size_t)info.luma_channels[2]);
            o[i] = (float)(0.2126 * r + 0.7152 * g + 0.0722 * b); // Rec. 709
        }
    } else if (info.u32_to_f64) {
        std::vector<uint32_t> tmp(n);
        file->read(s, h, info.channel, info.channel + 1, tmp.data());
        double *o = (double *)out;
        for (size_t i = 0; i < n; i++) o[i] = (double)tmp[i];
    } else {
        file->read(s, h, info.channel, info.channel + 1, out);
    }
    file->close();
}

void read_parallel(const std::vector<Slice> &slices, const StackInfo &info, int threads,
                   const std::function<void *(int64_t)> &target,
                   const std::function<void(int64_t, const void *)> &sink,
                   const std::function<bool(double)> &progress) {
    // Progress first after 50 ms; an out-of-memory or internal error ranks
    // after every slice's IoError (the message names a file when one failed).
    SlicePool pool{"reading slices", "cannot start reader threads", false, false};
    read_slices_parallel(
        (int64_t)slices.size(), threads,
        [&](int64_t k, std::vector<char> &scratch) {
            void *dst = target ? target(k) : nullptr;
            if (!dst) {
                if (scratch.empty()) scratch.resize(info.slice_bytes());
                dst = scratch.data();
            }
            read_slice(slices[(size_t)k], info, dst);
            if (sink) sink(k, dst);
        },
        progress, pool);
}

} // namespace isomend_io
