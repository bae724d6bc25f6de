// stack.cpp - opening, validating and decoding slices with OpenImageIO 2.4.
//
// What this file guards against (each checked by tests/io):
//   - OIIO's read_image() on a truncated TIFF returns *true* with has_error()
//     set, and a corrupt deflate strip can decode to zeros without any error
//     when the whole image is read at once.  We read scanline files row 0
//     first and the rest second, which forces OIIO's per-scanline path (that
//     path reports decode errors), and test has_error() after every call.
//   - Converting integers to float normalises (u16 23 -> 23/65535) and
//     int16 -> uint16 clamps negatives: we always ask for the *native* type
//     (half is widened to float, which is exact) and convert nothing else.
//   - Packed 12-bit TIFF (and other depths below the container's) comes back
//     scaled up to 16 bits; oiio:BitsPerSample tells the real depth and a
//     right shift restores the stored values (exact whether OIIO shifted or
//     replicated the bits).
//   - A slice whose data window is offset passes a width/height test: we
//     compare the whole data window, the channel count, the channel's type,
//     the bit depth and the depth with the first slice's.
//   - Multi-page TIFFs do not set oiio:subimages: pages are counted with
//     seek_subimage() probes (and the pending error is cleared).  Reaching
//     page k walks k IFDs in OIIO, so pages are opened directly instead
//     (TiffPageProxy): O(n) instead of O(n^2) for an n-page file.
#include "internal.hpp"

#include <algorithm>
#include <chrono>
#include <cmath>
#include <condition_variable>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <memory>
#include <mutex>
#include <thread>

#include <OpenImageIO/filesystem.h>
#include <OpenImageIO/imageio.h>

namespace isomend_io {

using OIIO::ImageInput;
using OIIO::ImageSpec;
using OIIO::TypeDesc;

void init_oiio() {
    static std::once_flag once;
    std::call_once(once, [] {
        // We run our own slice workers; OIIO's strip threads would only compete.
        OIIO::attribute("tiff:multithread", 0);
    });
}

size_t StackInfo::sample_size() const { return isomend_type_size(type); }

static std::string slice_name(const Slice &s) {
    if (!s.multipage) return s.path;
    return s.path + " (page " + std::to_string(s.subimage + 1) + ")";
}

static std::string take_oiio_error(ImageInput *in) {
    std::string e = in ? in->geterror() : std::string();
    std::string g = OIIO::geterror();
    if (e.empty()) e = g;
    while (!e.empty() && (e.back() == '\n' || e.back() == ' ')) e.pop_back();
    return e.empty() ? std::string("unknown OpenImageIO error") : e;
}

static std::unique_ptr<ImageInput> open_input(const std::string &path) {
    init_oiio();
    if (!is_regular_file(path))
        throw IoError(ISOMEND_IO_ERR_NOT_FOUND, path + ": file not found");
    auto in = ImageInput::open(path);
    if (!in) {
        std::string why = take_oiio_error(nullptr);
        throw IoError(ISOMEND_IO_ERR_UNREADABLE, path + ": cannot read this file: " + why);
    }
    return in;
}

// Stepping through pages one by one costs a full header parse per page
// (0.76 s for 600 TIFF pages); a seek straight to page k is cheap, so probe
// 1, 2, 4, ... and bisect: O(log n) seeks.
// OIIO 2.4 reaches TIFF page k by walking the k IFDs before it, so visiting
// every page of an n-page file costs O(n^2) (8 s for 2000 pages).  A page is
// opened directly instead: this proxy serves the file unchanged except for the
// header's first-IFD offset, which points at the page, so OIIO sees that page
// as page 0 of the file (and reports its own errors with the real path).
class TiffPageProxy final : public OIIO::Filesystem::IOFile {
  public:
    TiffPageProxy(const Slice &s) : IOFile(s.path, Read) {
        at_ = s.big_tiff ? 8 : 4;
        len_ = s.big_tiff ? 8 : 4;
        for (size_t i = 0; i < len_; i++) {
            size_t shift = 8 * (s.big_endian ? len_ - 1 - i : i);
            patch_[i] = (unsigned char)(s.ifd >> shift);
        }
    }
    size_t read(void *buf, size_t size) override {
        int64_t pos = tell();
        size_t n = IOFile::read(buf, size);
        fix(buf, n, pos);
        return n;
    }
    size_t pread(void *buf, size_t size, int64_t offset) override {
        size_t n = IOFile::pread(buf, size, offset);
        fix(buf, n, offset);
        return n;
    }

  private:
    void fix(void *buf, size_t n, int64_t pos) const {
        for (size_t i = 0; i < len_; i++) {
            int64_t q = at_ + (int64_t)i;
            if (q >= pos && q < pos + (int64_t)n) ((unsigned char *)buf)[q - pos] = patch_[i];
        }
    }
    unsigned char patch_[8] = {};
    int64_t at_ = 4;
    size_t len_ = 4;
};

// An open slice: the input and, for a directly opened TIFF page, its proxy
// (declared first: destroyed after the input that reads through it).
struct SliceInput {
    std::unique_ptr<TiffPageProxy> proxy;
    std::unique_ptr<ImageInput> in;
    int subimage = 0; // the subimage to pass to OIIO
    ~SliceInput() {
        if (in) in->close();
        in.reset();
    }
};

static void open_slice(const Slice &s, SliceInput &si) {
    if (s.ifd == 0) {
        si.in = open_input(s.path);
        si.subimage = s.subimage;
        return;
    }
    init_oiio();
    if (!is_regular_file(s.path)) throw IoError(ISOMEND_IO_ERR_NOT_FOUND, s.path + ": file not found");
    si.proxy.reset(new TiffPageProxy(s));
    if (!si.proxy->opened())
        throw IoError(ISOMEND_IO_ERR_UNREADABLE, s.path + ": cannot open the file");
    si.in = ImageInput::open(s.path, nullptr, si.proxy.get());
    if (!si.in)
        throw IoError(ISOMEND_IO_ERR_CORRUPT, slice_name(s) + ": cannot read the page: " + take_oiio_error(nullptr));
    si.subimage = 0;
}

int count_subimages(const std::string &path) {
    auto in = open_input(path);
    auto exists = [&](int k) {
        bool ok = in->seek_subimage(k, 0);
        if (!ok) {
            (void)in->geterror(); // a failed seek leaves an error pending
            (void)OIIO::geterror();
        }
        return ok;
    };
    int lo = 0, hi = 1; // page lo exists; find the first missing page
    while (hi < (1 << 24) && exists(hi)) {
        lo = hi;
        hi *= 2;
    }
    while (hi - lo > 1) {
        int mid = lo + (hi - lo) / 2;
        if (exists(mid)) lo = mid;
        else hi = mid;
    }
    in->close();
    return lo + 1;
}

static bool map_type(unsigned basetype, isomend_type *t, bool *u32_to_f64) {
    *u32_to_f64 = false;
    switch (basetype) {
    case TypeDesc::UINT8: *t = ISOMEND_U8; return true;
    case TypeDesc::INT8: *t = ISOMEND_I8; return true;
    case TypeDesc::UINT16: *t = ISOMEND_U16; return true;
    case TypeDesc::INT16: *t = ISOMEND_I16; return true;
    case TypeDesc::INT32: *t = ISOMEND_I32; return true;
    case TypeDesc::UINT32: *t = ISOMEND_F64; *u32_to_f64 = true; return true;
    case TypeDesc::HALF: *t = ISOMEND_F32; return true;
    case TypeDesc::FLOAT: *t = ISOMEND_F32; return true;
    case TypeDesc::DOUBLE: *t = ISOMEND_F64; return true;
    default: return false;
    }
}

// The type we ask OIIO for: the native one, except half (read as float).
static TypeDesc read_type(unsigned basetype) {
    if (basetype == TypeDesc::HALF) return TypeDesc::FLOAT;
    return TypeDesc((TypeDesc::BASETYPE)basetype);
}

static unsigned channel_basetype(const ImageSpec &spec, int c) {
    return spec.channelformat(c).basetype;
}

static std::string size_text(const ImageSpec &s) {
    std::string t = std::to_string(s.width) + "x" + std::to_string(s.height);
    if (s.x != 0 || s.y != 0) t += " at (" + std::to_string(s.x) + "," + std::to_string(s.y) + ")";
    return t;
}

static std::string info_size_text(const StackInfo &i) {
    std::string t = std::to_string(i.width) + "x" + std::to_string(i.height);
    if (i.xorigin != 0 || i.yorigin != 0)
        t += " at (" + std::to_string(i.xorigin) + "," + std::to_string(i.yorigin) + ")";
    return t;
}

static std::string channel_names(const ImageSpec &s) {
    std::string t;
    for (int c = 0; c < s.nchannels; c++) {
        if (c) t += ",";
        t += c < (int)s.channelnames.size() && !s.channelnames[c].empty() ? s.channelnames[c]
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
// OIIO hands resolution tags over as float (~7 digits): 1/1.3333334f is
// 0.74999996.  Rounding the spacing to 6 significant digits restores the
// decimal value that was written (0.75) without inventing precision.
static double round_significant(double v) {
    if (!(v > 0) || !std::isfinite(v)) return v;
    double scale = std::pow(10.0, 5 - (int)std::floor(std::log10(v)));
    return std::round(v * scale) / scale;
}

static void spacing_from_metadata(const ImageSpec &spec, StackInfo &info) {
    std::string desc = spec.get_string_attribute("ImageDescription");
    bool imagej = desc.rfind("ImageJ=", 0) == 0;
    float xres = spec.get_float_attribute("XResolution", 0.0f);
    float yres = spec.get_float_attribute("YResolution", 0.0f);
    std::string unit = spec.get_string_attribute("ResolutionUnit");
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
static void refuse_imagej_hyperstack(const Slice &s, const ImageSpec &spec) {
    std::string desc = spec.get_string_attribute("ImageDescription");
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

// OpenImageIO 2.4.7 reads a TIFF without a BitsPerSample tag (legal: the
// default is 1, bilevel; tifffile and Pillow write 1-bit images that way) as
// 8-bit and returns the packed bits as bytes, silently.  We read the tag
// ourselves: for every page of `path`, whether tag 258 is absent.  Classic
// and BigTIFF, either byte order; an unreadable structure returns what was
// read so far (OIIO reports real damage itself).
struct TiffLayout {
    bool big_tiff = false, big_endian = false;
    std::vector<uint64_t> ifd;   // offset of every page's IFD
    std::vector<bool> no_bits;   // page lacks BitsPerSample
};

static TiffLayout tiff_layout(const std::string &path);

static std::vector<bool> tiff_pages_without_bits_tag(const std::string &path) {
    return tiff_layout(path).no_bits;
}

void locate_tiff_pages(std::vector<Slice> &slices) {
    if (slices.size() < 2) return;
    TiffLayout t = tiff_layout(slices[0].path);
    if (t.ifd.size() != slices.size()) return;
    for (size_t k = 0; k < slices.size(); k++) {
        slices[k].ifd = t.ifd[k];
        slices[k].big_tiff = t.big_tiff;
        slices[k].big_endian = t.big_endian;
    }
}

static TiffLayout tiff_layout(const std::string &path) {
    TiffLayout layout;
    std::vector<bool> &out = layout.no_bits;
    FILE *f = std::fopen(path.c_str(), "rb");
    if (!f) return layout;
    unsigned char h[16];
    bool be = false;
    auto un = [&](const unsigned char *b, int n) -> uint64_t {
        uint64_t v = 0;
        for (int i = 0; i < n; i++) v |= (uint64_t)b[be ? n - 1 - i : i] << (8 * i);
        return v;
    };
    if (std::fread(h, 1, 16, f) >= 8 && h[0] == h[1] && (h[0] == 'I' || h[0] == 'M')) {
        be = h[0] == 'M';
        uint64_t magic = un(h + 2, 2);
        bool big_tiff = magic == 43;
        layout.big_tiff = big_tiff;
        layout.big_endian = be;
        uint64_t ifd = magic == 42 ? un(h + 4, 4) : big_tiff ? un(h + 8, 8) : 0;
        const int count_size = big_tiff ? 8 : 2, entry_size = big_tiff ? 20 : 12;
        const int next_size = big_tiff ? 8 : 4;
        while (ifd != 0 && ifd < (1ull << 62) && out.size() < (1u << 24)) {
            unsigned char c[8];
            if (std::fseek(f, (long)ifd, SEEK_SET) != 0 ||
                std::fread(c, 1, (size_t)count_size, f) != (size_t)count_size)
                break;
            uint64_t n = un(c, count_size);
            if (n == 0 || n > 4096) break;
            std::vector<unsigned char> e((size_t)n * (size_t)entry_size + (size_t)next_size);
            if (std::fread(e.data(), 1, e.size(), f) != e.size()) break;
            bool has_bits = false;
            for (uint64_t i = 0; i < n; i++)
                if (un(e.data() + i * (uint64_t)entry_size, 2) == 258) has_bits = true;
            out.push_back(!has_bits);
            layout.ifd.push_back(ifd);
            uint64_t next = un(e.data() + n * (uint64_t)entry_size, next_size);
            if (next <= ifd) break; // IFDs go forward in practice; this stops loops
            ifd = next;
        }
    }
    std::fclose(f);
    return layout;
}

static void describe_first(const Slice &s, const ImageSpec &spec, int channel,
                           StackInfo &info) {
    std::string name = slice_name(s);
    if (spec.depth > 1)
        throw IoError(ISOMEND_IO_ERR_UNSUPPORTED,
                      name + ": is a 3D image (depth " + std::to_string(spec.depth) +
                          "); only 2D slices can be stacked");
    if (spec.width < 1 || spec.height < 1 || spec.nchannels < 1)
        throw IoError(ISOMEND_IO_ERR_CORRUPT, name + ": empty image");
    if ((uint64_t)spec.width * (uint64_t)spec.height > (1ull << 50))
        throw IoError(ISOMEND_IO_ERR_UNSUPPORTED,
                      name + ": " + size_text(spec) + " pixels is beyond any memory");
    info.width = spec.width;
    info.height = spec.height;
    info.xorigin = spec.x;
    info.yorigin = spec.y;
    info.file_channels = spec.nchannels;
    info.bits = spec.get_int_attribute("oiio:BitsPerSample", 0);
    info.luma = false;
    if (channel == ISOMEND_IO_CHANNEL_AUTO) {
        if (spec.nchannels != 1)
            throw IoError(ISOMEND_IO_ERR_UNSUPPORTED,
                          name + ": has " + std::to_string(spec.nchannels) + " channels (" +
                              channel_names(spec) +
                              "); choose one with --channel N (0-based) or --channel luma");
        info.channel = 0;
    } else if (channel == ISOMEND_IO_CHANNEL_LUMA) {
        if (spec.nchannels < 3)
            throw IoError(ISOMEND_IO_ERR_UNSUPPORTED,
                          name + ": --channel luma needs 3 channels (R,G,B), the image has " +
                              std::to_string(spec.nchannels) + " (" + channel_names(spec) + ")");
        int r = spec.channelindex("R"), g = spec.channelindex("G"), b = spec.channelindex("B");
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
        if (channel >= spec.nchannels)
            throw IoError(ISOMEND_IO_ERR_UNSUPPORTED,
                          name + ": no channel " + std::to_string(channel) + "; the image has " +
                              std::to_string(spec.nchannels) + " (" + channel_names(spec) + ")");
        info.channel = channel;
    } else {
        throw IoError(ISOMEND_IO_ERR_INVALID_ARGUMENT, "invalid channel option " + std::to_string(channel));
    }
    info.file_type = channel_basetype(spec, info.channel);
    if (info.luma) {
        for (int k = 0; k < 3; k++)
            if (channel_basetype(spec, info.luma_channels[k]) != info.file_type)
                throw IoError(ISOMEND_IO_ERR_UNSUPPORTED,
                              name + ": --channel luma needs R, G and B of one sample type");
    }
    isomend_type t;
    bool u32 = false;
    if (!map_type(info.file_type, &t, &u32))
        throw IoError(ISOMEND_IO_ERR_UNSUPPORTED,
                      name + ": sample type " + std::string(TypeDesc((TypeDesc::BASETYPE)info.file_type).c_str()) +
                          " is not supported (u8, i8, u16, i16, i32, u32, half, float, double are)");
    info.type = info.luma ? ISOMEND_F32 : t;
    info.u32_to_f64 = u32 && !info.luma;
    info.shift = 0;
    int container_bits = (int)TypeDesc((TypeDesc::BASETYPE)info.file_type).size() * 8;
    bool unsigned_int = info.file_type == TypeDesc::UINT8 || info.file_type == TypeDesc::UINT16;
    if (unsigned_int && info.bits > 0 && info.bits < container_bits)
        info.shift = container_bits - info.bits;
    spacing_from_metadata(spec, info);
    if (s.multipage) refuse_imagej_hyperstack(s, spec);
}

static void check_against_first(const Slice &s, const ImageSpec &spec,
                                const StackInfo &info, const std::string &first_name) {
    std::string name = slice_name(s);
    std::string ref = " differs from the first slice's ";
    std::string tail = " (" + first_name + ")";
    if (spec.depth > 1)
        throw IoError(ISOMEND_IO_ERR_UNSUPPORTED,
                      name + ": is a 3D image (depth " + std::to_string(spec.depth) +
                          "); only 2D slices can be stacked");
    if (spec.width != info.width || spec.height != info.height || spec.x != info.xorigin ||
        spec.y != info.yorigin)
        throw IoError(ISOMEND_IO_ERR_MISMATCH,
                      name + ": size " + size_text(spec) + ref + info_size_text(info) + tail);
    if (spec.nchannels != info.file_channels)
        throw IoError(ISOMEND_IO_ERR_MISMATCH,
                      name + ": " + std::to_string(spec.nchannels) + " channels" + ref +
                          std::to_string(info.file_channels) + tail);
    unsigned bt = channel_basetype(spec, info.channel);
    if (bt != info.file_type)
        throw IoError(ISOMEND_IO_ERR_MISMATCH,
                      name + ": sample type " + std::string(TypeDesc((TypeDesc::BASETYPE)bt).c_str()) + ref +
                          std::string(TypeDesc((TypeDesc::BASETYPE)info.file_type).c_str()) + tail);
    int bits = spec.get_int_attribute("oiio:BitsPerSample", 0);
    if (bits != info.bits)
        throw IoError(ISOMEND_IO_ERR_MISMATCH,
                      name + ": " + std::to_string(bits) + " bits per sample" + ref +
                          std::to_string(info.bits) + tail);
}

// Per-thread state of the header scan: the open file and its page flags.
struct ScanCursor {
    std::unique_ptr<SliceInput> si;
    std::string open_path;
    std::string bits_tag_path;
    std::vector<bool> bits_tag_missing;
};

// Opens slice s's header (reusing the cursor's file) and runs the checks that
// need the file itself; returns its spec.
static ImageSpec scan_header(ScanCursor &c, const Slice &s) {
    // pages opened directly (s.ifd) get their own input each; files are reused
    if (!c.si || c.open_path != s.path || s.ifd != 0) {
        c.si.reset();
        c.si.reset(new SliceInput);
        open_slice(s, *c.si);
        c.open_path = s.path;
        if (!s.multipage) {
            // A multi-page file inside a folder/list would lose its pages silently.
            if (c.si->in->seek_subimage(1, 0)) {
                int pages = count_subimages(s.path);
                throw IoError(ISOMEND_IO_ERR_UNSUPPORTED,
                              s.path + ": has " + std::to_string(pages) +
                                  " pages/parts; a stack of files needs one image per file "
                                  "(open a multi-page file on its own)");
            }
            (void)c.si->in->geterror();
            (void)OIIO::geterror();
        }
    }
    ImageSpec spec;
    if (!c.si->in->seek_subimage(c.si->subimage, 0, spec))
        throw IoError(ISOMEND_IO_ERR_CORRUPT,
                      slice_name(s) + ": cannot read the header: " + take_oiio_error(c.si->in.get()));
    if (spec.format == TypeDesc::UINT8 && spec.get_int_attribute("oiio:BitsPerSample", 0) == 8 &&
        std::string(c.si->in->format_name()) == "tiff") {
        if (c.bits_tag_path != s.path) {
            c.bits_tag_missing = tiff_pages_without_bits_tag(s.path);
            c.bits_tag_path = s.path;
        }
        if ((size_t)s.subimage < c.bits_tag_missing.size() && c.bits_tag_missing[(size_t)s.subimage])
            throw IoError(ISOMEND_IO_ERR_UNSUPPORTED,
                          slice_name(s) + ": a 1-bit (bilevel) TIFF without a BitsPerSample tag, "
                                          "which OpenImageIO 2.4 misreads as 8-bit; save the mask "
                                          "as 8-bit");
    }
    return spec;
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
        ImageSpec spec = scan_header(c, slices[0]);
        describe_first(slices[0], spec, channel, info);
        info.format = c.si->in->format_name();
    }
    const size_t n = slices.size();
    if (threads <= 0) {
        unsigned hc = std::thread::hardware_concurrency();
        threads = hc ? (int)std::min(hc, 8u) : 2;
    }
    size_t workers = std::min<size_t>((size_t)threads, (n - 1 + 63) / 64); // >= 64 headers each
    if (workers <= 1) {
        ScanCursor c;
        for (size_t k = 1; k < n; k++) {
            ImageSpec spec = scan_header(c, slices[k]);
            check_against_first(slices[k], spec, info, first_name);
            if (progress && (k & 31) == 31) progress((double)(k + 1) / (double)n);
        }
        return;
    }
    std::atomic<size_t> done{1};
    std::atomic<bool> stop{false};
    std::mutex mu;
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
    };
    const size_t per = (n - 1 + workers - 1) / workers;
    auto worker = [&](size_t begin, size_t end) {
        try {
            ScanCursor c;
            for (size_t k = begin; k < end && !stop.load(); k++) {
                try {
                    ImageSpec spec = scan_header(c, slices[k]);
                    check_against_first(slices[k], spec, info, first_name);
                } catch (const IoError &e) {
                    fail(k, e.status, e.what());
                    return;
                }
                done.fetch_add(1);
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
        for (;;) {
            // at least one report, before any wait: a cancel is always seen
            if (progress) progress((double)done.load() / (double)n); // may throw (cancel)
            if (stop.load() || done.load() >= n) break;
            std::this_thread::sleep_for(std::chrono::milliseconds(20));
        }
    } catch (...) {
        join_all();
        throw;
    }
    for (auto &t : pool) t.join();
    if (error_index != SIZE_MAX) throw IoError(error_status, error_message);
}

// Reads channels [cb, ce) of one slice in type `t` into `dst` (packed).
static void decode(ImageInput *in, const Slice &s, int sub, const ImageSpec &spec, int cb,
                   int ce, TypeDesc t, void *dst) {
    bool ok;
    if (spec.tile_width == 0) {
        // Row 0 alone, then the rest: forces OIIO's per-scanline decoding,
        // the path that reports errors in compressed strips.
        size_t row = (size_t)spec.width * (size_t)(ce - cb) * t.size();
        ok = in->read_scanlines(sub, 0, spec.y, spec.y + 1, spec.z, cb, ce, t, dst);
        if (ok && spec.height > 1)
            ok = in->read_scanlines(sub, 0, spec.y + 1, spec.y + spec.height, spec.z, cb, ce, t,
                                    (char *)dst + row);
    } else {
        ok = in->read_image(sub, 0, cb, ce, t, dst);
    }
    if (!ok || in->has_error())
        throw IoError(ISOMEND_IO_ERR_CORRUPT,
                      slice_name(s) + ": corrupt or truncated image data: " + take_oiio_error(in));
}

template <typename T> static double as_double(const void *p, size_t i) {
    return (double)((const T *)p)[i];
}

static double sample_as_double(unsigned bt, const void *p, size_t i) {
    switch (bt) {
    case TypeDesc::UINT8: return as_double<uint8_t>(p, i);
    case TypeDesc::INT8: return as_double<int8_t>(p, i);
    case TypeDesc::UINT16: return as_double<uint16_t>(p, i);
    case TypeDesc::INT16: return as_double<int16_t>(p, i);
    case TypeDesc::INT32: return as_double<int32_t>(p, i);
    case TypeDesc::UINT32: return as_double<uint32_t>(p, i);
    case TypeDesc::DOUBLE: return as_double<double>(p, i);
    default: return as_double<float>(p, i); // float, and half read as float
    }
}

void read_slice(const Slice &s, const StackInfo &info, void *out) {
    SliceInput si;
    open_slice(s, si);
    ImageInput *in = si.in.get();
    ImageSpec spec;
    if (!in->seek_subimage(si.subimage, 0, spec))
        throw IoError(ISOMEND_IO_ERR_CORRUPT,
                      slice_name(s) + ": cannot read the header: " + take_oiio_error(in));
    // The file may have changed since isomend_io_open(): check again (cheap).
    check_against_first(s, spec, info, "as opened");
    size_t n = (size_t)info.width * (size_t)info.height;
    TypeDesc t = read_type(info.file_type);
    if (info.luma) {
        std::vector<char> tmp(n * (size_t)info.file_channels * t.size());
        decode(in, s, si.subimage, spec, 0, info.file_channels, t, tmp.data());
        float *o = (float *)out;
        size_t nc = (size_t)info.file_channels;
        for (size_t i = 0; i < n; i++) {
            double r = sample_as_double(t.basetype, tmp.data(), i * nc + (size_t)info.luma_channels[0]);
            double g = sample_as_double(t.basetype, tmp.data(), i * nc + (size_t)info.luma_channels[1]);
            double b = sample_as_double(t.basetype, tmp.data(), i * nc + (size_t)info.luma_channels[2]);
            o[i] = (float)(0.2126 * r + 0.7152 * g + 0.0722 * b); // Rec. 709
        }
    } else if (info.u32_to_f64) {
        std::vector<uint32_t> tmp(n);
        decode(in, s, si.subimage, spec, info.channel, info.channel + 1, t, tmp.data());
        double *o = (double *)out;
        for (size_t i = 0; i < n; i++) o[i] = (double)tmp[i];
    } else {
        decode(in, s, si.subimage, spec, info.channel, info.channel + 1, t, out);
        if (info.shift > 0) {
            if (info.file_type == TypeDesc::UINT16) {
                uint16_t *o = (uint16_t *)out;
                for (size_t i = 0; i < n; i++) o[i] = (uint16_t)(o[i] >> info.shift);
            } else {
                uint8_t *o = (uint8_t *)out;
                for (size_t i = 0; i < n; i++) o[i] = (uint8_t)(o[i] >> info.shift);
            }
        }
    }
    in->close();
    if (in->has_error())
        throw IoError(ISOMEND_IO_ERR_CORRUPT,
                      slice_name(s) + ": error while closing: " + take_oiio_error(in));
}

void read_parallel(const std::vector<Slice> &slices, const StackInfo &info, int threads,
                   const std::function<void *(int64_t)> &target,
                   const std::function<void(int64_t, const void *)> &sink,
                   const std::function<bool(double)> &progress) {
    const int64_t n = (int64_t)slices.size();
    if (threads <= 0) {
        unsigned hc = std::thread::hardware_concurrency();
        threads = hc ? (int)std::min(hc, 8u) : 2;
    }
    threads = (int)std::min<int64_t>(threads, std::max<int64_t>(n, 1));

    std::atomic<int64_t> next{0};
    std::atomic<int64_t> done{0};
    std::atomic<bool> stop{false};
    std::mutex mu;
    std::condition_variable cv;
    int64_t error_index = -1;
    isomend_io_status error_status = ISOMEND_IO_OK;
    std::string error_message;

    auto worker = [&]() {
        std::vector<char> buf;
        try {
            while (!stop.load()) {
                int64_t k = next.fetch_add(1);
                if (k >= n) break;
                void *dst = target ? target(k) : nullptr;
                if (!dst) {
                    if (buf.empty()) buf.resize(info.slice_bytes());
                    dst = buf.data();
                }
                try {
                    read_slice(slices[(size_t)k], info, dst);
                    if (sink) sink(k, dst);
                } catch (const IoError &e) {
                    std::lock_guard<std::mutex> lock(mu);
                    if (error_index < 0 || k < error_index) {
                        error_index = k;
                        error_status = e.status;
                        error_message = e.what();
                    }
                    stop.store(true);
                }
                done.fetch_add(1);
                cv.notify_one();
            }
        } catch (const std::bad_alloc &) {
            std::lock_guard<std::mutex> lock(mu);
            if (error_index < 0) {
                error_index = n;
                error_status = ISOMEND_IO_ERR_OUT_OF_MEMORY;
                error_message = "out of memory while reading slices";
            }
            stop.store(true);
        } catch (const std::exception &e) {
            std::lock_guard<std::mutex> lock(mu);
            if (error_index < 0) {
                error_index = n;
                error_status = ISOMEND_IO_ERR_INTERNAL;
                error_message = std::string("internal error while reading slices: ") + e.what();
            }
            stop.store(true);
        }
        cv.notify_one();
    };

    std::vector<std::thread> pool;
    bool cancelled = false;
    try {
        for (int t = 0; t < threads; t++) pool.emplace_back(worker);
    } catch (const std::system_error &) {
        stop.store(true);
        for (auto &th : pool) th.join();
        throw IoError(ISOMEND_IO_ERR_INTERNAL, "cannot start reader threads");
    }
    auto last = std::chrono::steady_clock::now();
    {
        std::unique_lock<std::mutex> lock(mu);
        while (done.load() < n && !stop.load()) {
            cv.wait_for(lock, std::chrono::milliseconds(50));
            auto now = std::chrono::steady_clock::now();
            if (progress && now - last >= std::chrono::milliseconds(50)) {
                last = now;
                double f = (double)done.load() / (double)n;
                lock.unlock();
                bool cancel = progress(f); // calling thread, lock not held
                lock.lock();
                if (cancel) {
                    cancelled = true;
                    stop.store(true);
                }
            }
        }
    }
    for (auto &th : pool) th.join();
    if (error_index >= 0) throw IoError(error_status, error_message);
    if (cancelled) throw IoError(ISOMEND_IO_ERR_CANCELLED, "cancelled while reading slices");
    if (progress && progress(1.0))
        throw IoError(ISOMEND_IO_ERR_CANCELLED, "cancelled while reading slices");
}

} // namespace isomend_io
