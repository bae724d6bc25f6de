// image_oiio.cpp - image.hpp on OpenImageIO 2.4+ (every format it reads).
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
//     replicated the bits).  A 1, 2 or 4-bit grey PNG comes back scaled to 8
//     bits without any attribute saying so: its depth is read from the
//     file's IHDR chunk instead, and shifted back the same way.
//   - OIIO 2.4.7 reads a TIFF without a BitsPerSample tag (legal: the
//     default is 1, bilevel; tifffile and Pillow write 1-bit images that way)
//     as 8-bit and returns the packed bits as bytes, silently: refused.
//   - OIIO premultiplies colour by alpha (PNG, TIFF with unassociated alpha)
//     unless asked not to: opened with oiio:UnassociatedAlpha, so colour
//     samples are the stored ones.
//   - Multi-page TIFFs do not set oiio:subimages: pages are counted with
//     seek_subimage() probes (and the pending error is cleared).  Reaching
//     page k walks k IFDs in OIIO, so pages are opened directly instead
//     (TiffPageProxy): O(n) instead of O(n^2) for an n-page file.
#include "image.hpp"

#include <cstdio>
#include <cstring>
#include <mutex>

#include <OpenImageIO/filesystem.h>
#include <OpenImageIO/imageio.h>

namespace isomend_io {

using OIIO::ImageInput;
using OIIO::ImageSpec;
using OIIO::TypeDesc;

void init_images() {
    static std::once_flag once;
    std::call_once(once, [] {
        // We run our own slice workers; OIIO's strip threads would only compete.
        OIIO::attribute("tiff:multithread", 0);
    });
}

std::string image_backend() { return std::string("OpenImageIO ") + OIIO_VERSION_STRING; }

static std::string take_oiio_error(ImageInput *in) {
    std::string e = in ? in->geterror() : std::string();
    std::string g = OIIO::geterror();
    if (e.empty()) e = g;
    while (!e.empty() && (e.back() == '\n' || e.back() == ' ')) e.pop_back();
    return e.empty() ? std::string("unknown OpenImageIO error") : e;
}

// Open options: stored samples, not premultiplied by alpha.
static const ImageSpec &open_config() {
    static const ImageSpec config = [] {
        ImageSpec c;
        c.attribute("oiio:UnassociatedAlpha", 1);
        return c;
    }();
    return config;
}

static std::unique_ptr<ImageInput> open_input(const std::string &path) {
    init_images();
    if (!is_regular_file(path))
        throw IoError(ISOMEND_IO_ERR_NOT_FOUND, path + ": file not found");
    auto in = ImageInput::open(path, &open_config());
    if (!in) {
        std::string why = take_oiio_error(nullptr);
        throw IoError(ISOMEND_IO_ERR_UNREADABLE, path + ": cannot read this file: " + why);
    }
    return in;
}

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

static Sample sample_of(TypeDesc t) {
    switch (t.basetype) {
    case TypeDesc::UINT8: return Sample::U8;
    case TypeDesc::INT8: return Sample::I8;
    case TypeDesc::UINT16: return Sample::U16;
    case TypeDesc::INT16: return Sample::I16;
    case TypeDesc::UINT32: return Sample::U32;
    case TypeDesc::INT32: return Sample::I32;
    case TypeDesc::HALF: return Sample::HALF;
    case TypeDesc::FLOAT: return Sample::FLOAT;
    case TypeDesc::DOUBLE: return Sample::DOUBLE;
    default: return Sample::OTHER;
    }
}

// The type we ask OIIO for: the native one, except half (read as float).
static TypeDesc read_type(Sample t) {
    switch (t) {
    case Sample::U8: return TypeDesc::UINT8;
    case Sample::I8: return TypeDesc::INT8;
    case Sample::U16: return TypeDesc::UINT16;
    case Sample::I16: return TypeDesc::INT16;
    case Sample::U32: return TypeDesc::UINT32;
    case Sample::I32: return TypeDesc::INT32;
    case Sample::DOUBLE: return TypeDesc::DOUBLE;
    default: return TypeDesc::FLOAT; // float, half
    }
}

// A PNG's bit depth if it is a grey image of 1, 2 or 4 bits without a tRNS
// chunk (with one, OpenImageIO adds alpha and the grey stays 8-bit), else 0.
static int png_low_grey_bits(const std::string &path) {
    unsigned char h[26];
    FILE *f = std::fopen(path.c_str(), "rb");
    if (!f) return 0;
    int bits = 0;
    if (std::fread(h, 1, sizeof h, f) == sizeof h && std::memcmp(h, "\x89PNG\r\n\x1a\n", 8) == 0 &&
        std::memcmp(h + 12, "IHDR", 4) == 0 && h[25] == 0 && h[24] < 8) {
        bits = h[24];
        // chunks after IHDR (length, type, data, CRC) up to the image data
        long at = 8 + 8 + 13 + 4;
        unsigned char c[8];
        while (std::fseek(f, at, SEEK_SET) == 0 && std::fread(c, 1, 8, f) == 8) {
            uint32_t len = (uint32_t)c[0] << 24 | (uint32_t)c[1] << 16 | (uint32_t)c[2] << 8 | c[3];
            if (std::memcmp(c + 4, "IDAT", 4) == 0) break;
            if (std::memcmp(c + 4, "tRNS", 4) == 0) {
                bits = 0;
                break;
            }
            at += 12 + (long)len;
        }
    }
    std::fclose(f);
    return bits;
}

class OiioFile final : public ImageFile {
  public:
    explicit OiioFile(const Slice &s) : path_(s.path), ifd_(s.ifd) {
        if (s.ifd == 0) {
            in_ = open_input(s.path);
            return;
        }
        init_images();
        if (!is_regular_file(s.path)) throw IoError(ISOMEND_IO_ERR_NOT_FOUND, s.path + ": file not found");
        proxy_.reset(new TiffPageProxy(s));
        if (!proxy_->opened())
            throw IoError(ISOMEND_IO_ERR_UNREADABLE, s.path + ": cannot open the file");
        // The proxy goes in the configuration too: given a configuration, OIIO
        // 2.4 opens by name and ignores the proxy argument.
        ImageSpec config = open_config();
        OIIO::Filesystem::IOProxy *proxy = proxy_.get();
        config.attribute("oiio:ioproxy", TypeDesc::PTR, &proxy);
        in_ = ImageInput::open(s.path, &config, proxy);
        if (!in_)
            throw IoError(ISOMEND_IO_ERR_CORRUPT,
                          slice_name(s) + ": cannot read the page: " + take_oiio_error(nullptr));
    }
    ~OiioFile() override {
        if (in_) in_->close();
        in_.reset(); // before the proxy it reads through
    }

    std::string format() const override { return in_->format_name(); }

    bool serves(const Slice &s) const override {
        // pages opened directly (ifd) get an input each; a file serves its pages
        return s.path == path_ && s.ifd == 0 && ifd_ == 0;
    }

    bool has_subimage(int k) override {
        bool ok = in_->seek_subimage(k, 0);
        if (!ok) {
            (void)in_->geterror(); // a failed seek leaves an error pending
            (void)OIIO::geterror();
        }
        return ok;
    }

    ImageHeader header(const Slice &s) override {
        ImageSpec spec;
        if (!in_->seek_subimage(subimage(s), 0, spec))
            throw IoError(ISOMEND_IO_ERR_CORRUPT,
                          slice_name(s) + ": cannot read the header: " + take_oiio_error(in_.get()));
        ImageHeader h;
        h.width = spec.width;
        h.height = spec.height;
        h.depth = spec.depth;
        h.x = spec.x;
        h.y = spec.y;
        for (int c = 0; c < spec.nchannels; c++) {
            h.channel_types.push_back(sample_of(spec.channelformat(c)));
            h.channel_names.push_back(c < (int)spec.channelnames.size() ? spec.channelnames[c] : "");
        }
        h.bits = spec.get_int_attribute("oiio:BitsPerSample", 0);
        std::string fmt = in_->format_name();
        if (fmt == "png" && h.bits == 0 && spec.format == TypeDesc::UINT8) h.bits = png_low_grey_bits(path_);
        h.description = spec.get_string_attribute("ImageDescription");
        h.xres = spec.get_float_attribute("XResolution", 0.0f);
        h.yres = spec.get_float_attribute("YResolution", 0.0f);
        h.resolution_unit = spec.get_string_attribute("ResolutionUnit");
        if (spec.format == TypeDesc::UINT8 && h.bits == 8 && fmt == "tiff" && lacks_bits_tag(s))
            throw IoError(ISOMEND_IO_ERR_UNSUPPORTED,
                          slice_name(s) + ": a 1-bit (bilevel) TIFF without a BitsPerSample tag, "
                                          "which OpenImageIO 2.4 misreads as 8-bit; save the mask "
                                          "as 8-bit");
        return h;
    }

    void read(const Slice &s, const ImageHeader &h, int cb, int ce, void *dst) override {
        ImageSpec spec;
        int sub = subimage(s);
        if (!in_->seek_subimage(sub, 0, spec))
            throw IoError(ISOMEND_IO_ERR_CORRUPT,
                          slice_name(s) + ": cannot read the header: " + take_oiio_error(in_.get()));
        Sample st = h.channel_types[(size_t)cb];
        TypeDesc t = read_type(st);
        // The file's own type asked as "native" (UNKNOWN): the same bytes, read
        // straight into dst.  Asked by name, OIIO 2.4 reads through a 16 MB
        // buffer allocated and unmapped at every call, whose pages fault in
        // anew each slice (128 faults a 512 x 512 u16 slice; docs/slices.md).
        TypeDesc ask = t == spec.format && spec.channelformats.empty() ? TypeDesc::UNKNOWN : t;
        bool ok;
        if (spec.tile_width == 0 && st != Sample::DOUBLE) {
            // Row 0 alone, then the rest: forces OIIO's per-scanline decoding,
            // the path that reports errors in compressed strips.  (Not for
            // 64-bit samples: OIIO 2.4.7 returns zeros for part of a strip of
            // doubles, without an error.)
            size_t row = (size_t)spec.width * (size_t)(ce - cb) * t.size();
            ok = in_->read_scanlines(sub, 0, spec.y, spec.y + 1, spec.z, cb, ce, ask, dst);
            if (ok && spec.height > 1)
                ok = in_->read_scanlines(sub, 0, spec.y + 1, spec.y + spec.height, spec.z, cb, ce, ask,
                                         (char *)dst + row);
        } else {
            ok = in_->read_image(sub, 0, cb, ce, t, dst);
        }
        if (!ok || in_->has_error())
            throw IoError(ISOMEND_IO_ERR_CORRUPT,
                          slice_name(s) + ": corrupt or truncated image data: " + take_oiio_error(in_.get()));
        // Depths below the container's come back scaled up: shift them back.
        int container = st == Sample::U8 ? 8 : st == Sample::U16 ? 16 : 0;
        if (container && h.bits > 0 && h.bits < container) {
            int shift = container - h.bits;
            size_t n = (size_t)h.width * (size_t)h.height * (size_t)(ce - cb);
            if (st == Sample::U16) {
                uint16_t *o = (uint16_t *)dst;
                for (size_t i = 0; i < n; i++) o[i] = (uint16_t)(o[i] >> shift);
            } else {
                uint8_t *o = (uint8_t *)dst;
                for (size_t i = 0; i < n; i++) o[i] = (uint8_t)(o[i] >> shift);
            }
        }
        slice_ = slice_name(s);
    }

    void close() override {
        in_->close();
        if (in_->has_error())
            throw IoError(ISOMEND_IO_ERR_CORRUPT, slice_ + ": error while closing: " + take_oiio_error(in_.get()));
    }

  private:
    // The subimage to ask OIIO for: 0 for a page opened directly.
    int subimage(const Slice &s) const { return s.ifd != 0 ? 0 : s.subimage; }

    bool lacks_bits_tag(const Slice &s) {
        if (s.ifd != 0) return s.no_bits_tag; // found when the pages were located
        if (!layout_read_) {
            no_bits_ = tiff_layout(path_).no_bits;
            layout_read_ = true;
        }
        return (size_t)s.subimage < no_bits_.size() && no_bits_[(size_t)s.subimage];
    }

    std::string path_;
    uint64_t ifd_ = 0;
    std::unique_ptr<TiffPageProxy> proxy_; // declared first: destroyed after in_
    std::unique_ptr<ImageInput> in_;
    bool layout_read_ = false;
    std::vector<bool> no_bits_;
    std::string slice_;
};

std::unique_ptr<ImageFile> open_image(const Slice &s) { return std::unique_ptr<ImageFile>(new OiioFile(s)); }

// Stepping through pages one by one costs a full header parse per page
// (0.76 s for 600 TIFF pages); a seek straight to page k is cheap, so probe
// 1, 2, 4, ... and bisect: O(log n) seeks.
int count_subimages(const std::string &path) {
    Slice s;
    s.path = path;
    OiioFile f(s);
    int lo = 0, hi = 1; // page lo exists; find the first missing page
    while (hi < (1 << 24) && f.has_subimage(hi)) {
        lo = hi;
        hi *= 2;
    }
    while (hi - lo > 1) {
        int mid = lo + (hi - lo) / 2;
        if (f.has_subimage(mid)) lo = mid;
        else hi = mid;
    }
    return lo + 1;
}

// The extensions OpenImageIO can read ("tif", "exr", ...).
std::set<std::string> image_extensions() {
    init_images();
    std::set<std::string> exts;
    std::string list = OIIO::get_string_attribute("extension_list");
    // "tiff:tif,tiff,tx;openexr:exr,sxr;..."
    size_t i = 0;
    while (i < list.size()) {
        size_t semi = list.find(';', i);
        if (semi == std::string::npos) semi = list.size();
        std::string item = list.substr(i, semi - i);
        size_t colon = item.find(':');
        if (colon != std::string::npos) {
            std::string e = item.substr(colon + 1);
            size_t k = 0;
            while (k <= e.size()) {
                size_t comma = e.find(',', k);
                if (comma == std::string::npos) comma = e.size();
                if (comma > k) {
                    std::string one = e.substr(k, comma - k);
                    for (char &c : one) c = (char)std::tolower((unsigned char)c);
                    exts.insert(one);
                }
                k = comma + 1;
            }
        }
        i = semi + 1;
    }
    return exts;
}

} // namespace isomend_io
