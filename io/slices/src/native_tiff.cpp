// native_tiff.cpp - TIFF slices with libtiff 4.5+ (see native.hpp).
//
// libtiff reports through handlers: each file gets its own (TIFFOpenExt's
// options), which keep the first error for the message and silence warnings,
// so the library never prints and threads never share an error state.  A
// decode is good only if libtiff returned the full strip or tile *and*
// reported no error.
//
// What OpenImageIO does and we do too, so that both backends agree: channel
// names Y, Y+A, R+G+B(+A), channelN beyond; MinIsWhite inverted for unsigned
// samples of 8 bits or fewer (not for wider or signed ones); palette images
// expanded to R, G, B (the colour map's 16 bits divided by 257, truncated); JPEG-compressed YCbCr
// delivered as RGB; XPosition/YPosition times the resolution as the data
// window origin; ResolutionUnit inch when absent.
#include "native.hpp"

#include <algorithm>
#include <cstdarg>
#include <cstdio>
#include <cstring>

#include <tiffio.h>

namespace isomend_io {

std::string tiff_version() {
    // "LIBTIFF, Version 4.5.0\nCopyright ..."
    std::string v = TIFFGetVersion();
    size_t p = v.find("Version ");
    size_t e = v.find('\n');
    return "libtiff " + (p == std::string::npos ? v : v.substr(p + 8, e == std::string::npos ? e : e - p - 8));
}

namespace {

struct Errors {
    std::string first;
    bool any = false;
    void clear() {
        first.clear();
        any = false;
    }
};

int on_error(TIFF *, void *user, const char *module, const char *fmt, va_list ap) {
    auto *e = (Errors *)user;
    if (!e->any) {
        char buf[512];
        std::vsnprintf(buf, sizeof buf, fmt, ap);
        e->first = module && *module ? std::string(module) + ": " + buf : std::string(buf);
    }
    e->any = true;
    return 1; // handled: libtiff's process-wide handler (stderr) is not called
}

int on_warning(TIFF *, void *, const char *, const char *, va_list) { return 1; }

// What a page is, as far as reading it goes.
struct Layout {
    uint32_t width = 0, height = 0, depth = 1;
    uint16_t spp = 1, bps = 1, format = SAMPLEFORMAT_UINT, photometric = PHOTOMETRIC_MINISBLACK;
    uint16_t planar = PLANARCONFIG_CONTIG, compression = COMPRESSION_NONE;
    bool palette = false; // expanded to R, G, B
    bool ycbcr_jpeg = false;
    uint16_t *colormap[3] = {nullptr, nullptr, nullptr};
};

Sample sample_type(uint16_t format, uint16_t bps) {
    switch (format) {
    case SAMPLEFORMAT_UINT:
    case SAMPLEFORMAT_VOID:
        if (bps >= 1 && bps <= 8) return Sample::U8;
        if (bps >= 9 && bps <= 16) return Sample::U16;
        if (bps == 32) return Sample::U32;
        return Sample::OTHER;
    case SAMPLEFORMAT_INT:
        if (bps == 8) return Sample::I8;
        if (bps == 16) return Sample::I16;
        if (bps == 32) return Sample::I32;
        return Sample::OTHER;
    case SAMPLEFORMAT_IEEEFP:
        if (bps == 16) return Sample::HALF;
        if (bps == 32) return Sample::FLOAT;
        if (bps == 64) return Sample::DOUBLE;
        return Sample::OTHER;
    default: return Sample::OTHER;
    }
}

class TiffFile final : public ImageFile {
  public:
    explicit TiffFile(const Slice &s) : path_(s.path) {
        TIFFOpenOptions *opts = TIFFOpenOptionsAlloc();
        if (!opts) throw std::bad_alloc();
        TIFFOpenOptionsSetErrorHandlerExtR(opts, on_error, &errors_);
        TIFFOpenOptionsSetWarningHandlerExtR(opts, on_warning, &errors_);
        // "m": no memory mapping (a file truncated under us is an error, not SIGBUS)
        tif_ = TIFFOpenExt(s.path.c_str(), "rm", opts);
        TIFFOpenOptionsFree(opts);
        if (!tif_)
            throw IoError(ISOMEND_IO_ERR_UNREADABLE,
                          s.path + ": cannot read this file: " + (errors_.any ? errors_.first : "not a TIFF file"));
    }
    ~TiffFile() override {
        if (tif_) TIFFClose(tif_);
    }

    std::string format() const override { return "tiff"; }
    bool serves(const Slice &s) const override { return s.path == path_; }

    bool has_subimage(int k) override { return k >= 0 && k < pages(); }

    int pages() {
        if (pages_ < 0) {
            errors_.clear();
            pages_ = (int)TIFFNumberOfDirectories(tif_);
            errors_.clear();
        }
        return pages_;
    }

    ImageHeader header(const Slice &s) override {
        Layout l = layout(s);
        ImageHeader h;
        h.width = (int)l.width;
        h.height = (int)l.height;
        h.depth = (int)l.depth;
        int nc = l.palette ? 3 : (int)l.spp;
        Sample t = l.palette || l.ycbcr_jpeg ? Sample::U8 : sample_type(l.format, l.bps);
        h.bits = l.palette || l.ycbcr_jpeg ? 8 : l.bps;
        uint16_t nextra = 0, *extra = nullptr;
        TIFFGetField(tif_, TIFFTAG_EXTRASAMPLES, &nextra, &extra);
        for (int c = 0; c < nc; c++) {
            h.channel_types.push_back(t);
            bool alpha = extra && nextra > 0 && (extra[0] == EXTRASAMPLE_ASSOCALPHA || extra[0] == EXTRASAMPLE_UNASSALPHA);
            std::string name;
            if (nc == 1) name = "Y";
            else if (nc == 2) name = c == 0 ? "Y" : alpha ? "A" : "channel1";
            else if (c < 3) name = std::string(1, "RGB"[c]);
            else if (c == 3 && alpha) name = "A";
            else name = "channel" + std::to_string(c);
            h.channel_names.push_back(name);
        }
        char *desc = nullptr;
        if (TIFFGetField(tif_, TIFFTAG_IMAGEDESCRIPTION, &desc) && desc) h.description = desc;
        float xres = 0, yres = 0;
        bool has_x = TIFFGetField(tif_, TIFFTAG_XRESOLUTION, &xres) != 0;
        bool has_y = TIFFGetField(tif_, TIFFTAG_YRESOLUTION, &yres) != 0;
        if (has_x) h.xres = xres;
        if (has_y) h.yres = yres;
        if (has_x || has_y) {
            uint16_t unit = RESUNIT_INCH;
            TIFFGetFieldDefaulted(tif_, TIFFTAG_RESOLUTIONUNIT, &unit);
            h.resolution_unit = unit == RESUNIT_NONE ? "none" : unit == RESUNIT_CENTIMETER ? "cm" : "in";
        }
        float xpos = 0, ypos = 0;
        if (TIFFGetField(tif_, TIFFTAG_XPOSITION, &xpos)) h.x = (int)(xpos * (has_x && xres > 0 ? xres : 1.0f));
        if (TIFFGetField(tif_, TIFFTAG_YPOSITION, &ypos)) h.y = (int)(ypos * (has_y && yres > 0 ? yres : 1.0f));
        return h;
    }

    void read(const Slice &s, const ImageHeader &h, int cb, int ce, void *dst) override {
        Layout l = layout(s);
        if (l.depth > 1 || h.channel_types.empty() || h.channel_types[0] == Sample::OTHER)
            throw IoError(ISOMEND_IO_ERR_UNSUPPORTED, slice_name(s) + ": cannot read this sample type");
        if (l.palette) {
            read_palette(s, l, cb, ce, (uint8_t *)dst);
            return;
        }
        Sample t = h.channel_types[0];
        int bps = l.ycbcr_jpeg ? 8 : l.bps;
        int spp = l.ycbcr_jpeg ? 3 : l.spp;
        bool invert = l.photometric == PHOTOMETRIC_MINISWHITE && t == Sample::U8;
        const bool separate = l.planar == PLANARCONFIG_SEPARATE;
        decode(s, l, spp, separate ? cb : 0, separate ? ce : 1,
               [&](int plane, const unsigned char *row, uint32_t x0, uint32_t n, uint32_t y) {
            // `row`: n pixels starting at column x0 of row y, `plane`'s samples
            int in_row = separate ? 1 : spp;
            for (int c = cb; c < ce; c++) {
                int src_c = separate ? 0 : c;
                if (separate && plane != c) continue;
                size_t out = ((size_t)y * l.width + x0) * (size_t)(ce - cb) + (size_t)(c - cb);
                store(t, bps, invert, row, in_row, src_c, n, dst, out, (size_t)(ce - cb));
            }
        });
    }

    void close() override {}

  private:
    // Makes s's page the current one and describes it.
    Layout layout(const Slice &s) {
        errors_.clear();
        int ok = s.ifd != 0 ? TIFFSetSubDirectory(tif_, s.ifd) : TIFFSetDirectory(tif_, (tdir_t)s.subimage);
        if (!ok)
            throw IoError(ISOMEND_IO_ERR_CORRUPT,
                          slice_name(s) + ": cannot read the header: " + (errors_.any ? errors_.first : "no such page"));
        Layout l;
        if (!TIFFGetField(tif_, TIFFTAG_IMAGEWIDTH, &l.width) || !TIFFGetField(tif_, TIFFTAG_IMAGELENGTH, &l.height))
            throw IoError(ISOMEND_IO_ERR_CORRUPT, slice_name(s) + ": cannot read the header: no image size");
        TIFFGetFieldDefaulted(tif_, TIFFTAG_IMAGEDEPTH, &l.depth);
        TIFFGetFieldDefaulted(tif_, TIFFTAG_SAMPLESPERPIXEL, &l.spp);
        TIFFGetFieldDefaulted(tif_, TIFFTAG_BITSPERSAMPLE, &l.bps);
        TIFFGetFieldDefaulted(tif_, TIFFTAG_SAMPLEFORMAT, &l.format);
        TIFFGetFieldDefaulted(tif_, TIFFTAG_PLANARCONFIG, &l.planar);
        TIFFGetFieldDefaulted(tif_, TIFFTAG_COMPRESSION, &l.compression);
        if (!TIFFGetField(tif_, TIFFTAG_PHOTOMETRIC, &l.photometric))
            l.photometric = l.spp >= 3 ? PHOTOMETRIC_RGB : PHOTOMETRIC_MINISBLACK;
        if (l.spp < 1 || l.width < 1 || l.height < 1)
            throw IoError(ISOMEND_IO_ERR_CORRUPT, slice_name(s) + ": empty image");
        switch (l.photometric) {
        case PHOTOMETRIC_MINISBLACK:
        case PHOTOMETRIC_MINISWHITE:
        case PHOTOMETRIC_RGB: break;
        case PHOTOMETRIC_PALETTE:
            if (l.spp != 1 || l.bps > 8 ||
                !TIFFGetField(tif_, TIFFTAG_COLORMAP, &l.colormap[0], &l.colormap[1], &l.colormap[2]))
                throw IoError(ISOMEND_IO_ERR_UNSUPPORTED,
                              slice_name(s) + ": a palette image with " + std::to_string(l.bps) +
                                  "-bit indices or no colour map");
            l.palette = true;
            break;
        case PHOTOMETRIC_YCBCR:
            if (l.compression != COMPRESSION_JPEG || l.spp != 3)
                throw IoError(ISOMEND_IO_ERR_UNSUPPORTED,
                              slice_name(s) + ": YCbCr samples that are not JPEG-compressed");
            TIFFSetField(tif_, TIFFTAG_JPEGCOLORMODE, JPEGCOLORMODE_RGB);
            l.ycbcr_jpeg = true;
            l.planar = PLANARCONFIG_CONTIG;
            break;
        default:
            throw IoError(ISOMEND_IO_ERR_UNSUPPORTED,
                          slice_name(s) + ": TIFF photometric interpretation " + std::to_string(l.photometric) +
                              " (only grey, RGB, palette and JPEG YCbCr are read)");
        }
        if (errors_.any)
            throw IoError(ISOMEND_IO_ERR_CORRUPT, slice_name(s) + ": cannot read the header: " + errors_.first);
        return l;
    }

    [[noreturn]] void corrupt(const Slice &s, const std::string &what) {
        throw IoError(ISOMEND_IO_ERR_CORRUPT, slice_name(s) + ": corrupt or truncated image data: " +
                                                  (errors_.any ? errors_.first : what));
    }

    // Decodes planes [p0, p1) of the page (contiguous samples: the one plane 0)
    // strip by strip or tile by tile and hands every decoded row piece to
    // emit(plane, bytes, x0, n, y).
    template <typename Emit>
    void decode(const Slice &s, const Layout &l, int spp, int p0, int p1, Emit &&emit) {
        const int bps = l.ycbcr_jpeg ? 8 : l.bps;
        const size_t per_pixel = (size_t)(l.planar == PLANARCONFIG_SEPARATE ? 1 : spp) * (size_t)bps;
        errors_.clear();
        if (TIFFIsTiled(tif_)) {
            uint32_t tw = 0, th = 0;
            TIFFGetField(tif_, TIFFTAG_TILEWIDTH, &tw);
            TIFFGetField(tif_, TIFFTAG_TILELENGTH, &th);
            tmsize_t size = TIFFTileSize(tif_);
            if (tw == 0 || th == 0 || size <= 0) corrupt(s, "bad tile size");
            const size_t row_bytes = ((size_t)tw * per_pixel + 7) / 8;
            if ((size_t)size < row_bytes * th) corrupt(s, "bad tile size");
            std::vector<unsigned char> buf((size_t)size);
            for (int p = p0; p < p1; p++)
                for (uint32_t ty = 0; ty < l.height; ty += th)
                    for (uint32_t tx = 0; tx < l.width; tx += tw) {
                        ttile_t tile = TIFFComputeTile(tif_, tx, ty, 0, (tsample_t)p);
                        tmsize_t got = TIFFReadEncodedTile(tif_, tile, buf.data(), size);
                        if (got < size || errors_.any) corrupt(s, "short tile " + std::to_string(tile));
                        uint32_t n = std::min(tw, l.width - tx);
                        for (uint32_t r = 0; r < th && ty + r < l.height; r++)
                            emit(p, buf.data() + r * row_bytes, tx, n, ty + r);
                    }
            return;
        }
        uint32_t rps = l.height;
        TIFFGetFieldDefaulted(tif_, TIFFTAG_ROWSPERSTRIP, &rps);
        if (rps == 0 || rps > l.height) rps = l.height;
        const size_t row_bytes = ((size_t)l.width * per_pixel + 7) / 8;
        tmsize_t size = TIFFStripSize(tif_);
        if (size <= 0 || (size_t)size < row_bytes * (size_t)rps) corrupt(s, "bad strip size");
        std::vector<unsigned char> buf((size_t)size);
        const uint32_t strips_per_plane = (l.height + rps - 1) / rps;
        for (int p = p0; p < p1; p++)
            for (uint32_t k = 0; k < strips_per_plane; k++) {
                uint32_t y0 = k * rps, rows = std::min(rps, l.height - y0);
                tstrip_t strip = (tstrip_t)((uint32_t)p * strips_per_plane + k);
                tmsize_t want = (tmsize_t)(row_bytes * rows);
                tmsize_t got = TIFFReadEncodedStrip(tif_, strip, buf.data(), want);
                if (got < want || errors_.any) corrupt(s, "short strip " + std::to_string(strip));
                for (uint32_t r = 0; r < rows; r++) emit(p, buf.data() + r * row_bytes, 0, l.width, y0 + r);
            }
    }

    // Stores sample `c` of n pixels (`in_row` samples each) of a decoded row
    // at out, out + stride, ... of dst, in the delivered type.
    static void store(Sample t, int bps, bool invert, const unsigned char *row, int in_row, int c,
                      uint32_t n, void *dst, size_t out, size_t stride) {
        switch (t) {
        case Sample::U8:
        case Sample::U16: {
            const uint32_t max = (1u << bps) - 1u;
            for (uint32_t i = 0; i < n; i++) {
                size_t k = (size_t)i * (size_t)in_row + (size_t)c;
                uint32_t v;
                if (bps == 8) v = row[k];
                else if (bps == 16) {
                    uint16_t w;
                    std::memcpy(&w, row + 2 * k, 2);
                    v = w;
                } else v = packed_sample(row, k, bps);
                if (invert) v = max - v;
                if (t == Sample::U8) ((uint8_t *)dst)[out + i * stride] = (uint8_t)v;
                else ((uint16_t *)dst)[out + i * stride] = (uint16_t)v;
            }
            return;
        }
        case Sample::HALF:
            for (uint32_t i = 0; i < n; i++) {
                uint16_t w;
                std::memcpy(&w, row + 2 * ((size_t)i * (size_t)in_row + (size_t)c), 2);
                ((float *)dst)[out + i * stride] = half_to_float(w);
            }
            return;
        default: {
            size_t size = delivered_size(t); // i8 1, i16 2, u32/i32/float 4, double 8
            for (uint32_t i = 0; i < n; i++)
                std::memcpy((char *)dst + (out + i * stride) * size,
                            row + size * ((size_t)i * (size_t)in_row + (size_t)c), size);
            return;
        }
        }
    }

    void read_palette(const Slice &s, const Layout &l, int cb, int ce, uint8_t *dst) {
        const size_t nc = (size_t)(ce - cb);
        const uint32_t entries = 1u << l.bps;
        decode(s, l, 1, 0, 1, [&](int, const unsigned char *row, uint32_t x0, uint32_t n, uint32_t y) {
            for (uint32_t i = 0; i < n; i++) {
                uint32_t index = l.bps == 8 ? row[i] : packed_sample(row, i, l.bps);
                if (index >= entries) index = entries - 1;
                size_t out = ((size_t)y * l.width + x0 + i) * nc;
                for (int c = cb; c < ce; c++) dst[out + (size_t)(c - cb)] = (uint8_t)(l.colormap[c][index] / 257);
            }
        });
    }

    std::string path_;
    Errors errors_; // the handlers write here: must outlive tif_
    TIFF *tif_ = nullptr;
    int pages_ = -1;
};

} // namespace

std::unique_ptr<ImageFile> open_tiff(const Slice &s) { return std::unique_ptr<ImageFile>(new TiffFile(s)); }

int tiff_pages(const std::string &path) {
    Slice s;
    s.path = path;
    TiffFile f(s);
    return std::max(f.pages(), 1);
}

} // namespace isomend_io
