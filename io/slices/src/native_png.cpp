// native_png.cpp - PNG slices with libpng 1.6 (see native.hpp).
//
// libpng reports errors by longjmp() out of the failing call: the decoding
// is one C-style function (png_decode) with no C++ object alive across the
// setjmp, which turns any error into a message; the class around it owns
// the buffers.  Warnings are dropped (nothing prints).
//
// As OpenImageIO reads PNG: palette images expand to R, G, B (and A with a
// tRNS chunk), a tRNS chunk on grey or RGB adds an alpha channel, 16-bit
// samples are delivered in the machine's order, no gamma is applied; pHYs in
// pixels per metre becomes pixels per inch ("inch"), an unknown pHYs unit
// "none"; oFFs in pixels is the data window origin.  Grey samples of 1, 2 or
// 4 bits are delivered as stored (0..15), like low-depth TIFF; with a tRNS
// chunk libpng expands them to 8 bits and they are delivered so.
#include "native.hpp"

#include <csetjmp>
#include <cstdio>
#include <cstring>

#include <png.h>

namespace isomend_io {

std::string png_version() { return std::string("libpng ") + png_get_libpng_ver(nullptr); }

namespace {

struct PngInfo {
    png_uint_32 width, height;
    int channels, depth;  // after the transforms: depth 8 or 16 (or the low grey depth)
    int stored_depth;     // the file's bit depth
    int colour;           // the file's colour type
    bool alpha;
    int has_phys, phys_unit;
    png_uint_32 phys_x, phys_y;
    int has_offs, offs_unit;
    png_int_32 offs_x, offs_y;
    char message[256];
};

struct ErrorSink {
    jmp_buf jump;
    char *message;
    size_t size;
};

void on_png_error(png_structp png, png_const_charp msg) {
    auto *sink = (ErrorSink *)png_get_error_ptr(png);
    std::snprintf(sink->message, sink->size, "%s", msg ? msg : "libpng error");
    longjmp(sink->jump, 1);
}

void on_png_warning(png_structp, png_const_charp) {}

// Reads the header (rows == nullptr) or the whole image into rows (one
// pointer per row, each info->width * channels * (depth / 8) bytes, or one
// byte per sample for a low grey depth).  Returns false with info->message set.
bool png_decode(FILE *f, PngInfo *info, unsigned char **rows) {
    ErrorSink sink;
    sink.message = info->message;
    sink.size = sizeof info->message;
    info->message[0] = 0;
    png_structp png = png_create_read_struct(PNG_LIBPNG_VER_STRING, &sink, on_png_error, on_png_warning);
    if (!png) {
        std::snprintf(info->message, sizeof info->message, "out of memory");
        return false;
    }
    png_infop pinfo = png_create_info_struct(png);
    if (!pinfo) {
        png_destroy_read_struct(&png, nullptr, nullptr);
        std::snprintf(info->message, sizeof info->message, "out of memory");
        return false;
    }
    if (setjmp(sink.jump)) {
        png_destroy_read_struct(&png, &pinfo, nullptr);
        return false;
    }
    png_init_io(png, f);
    png_read_info(png, pinfo);
    png_uint_32 w, h;
    int depth, colour, interlace;
    png_get_IHDR(png, pinfo, &w, &h, &depth, &colour, &interlace, nullptr, nullptr);
    info->width = w;
    info->height = h;
    info->stored_depth = depth;
    info->colour = colour;
    bool trns = png_get_valid(png, pinfo, PNG_INFO_tRNS) != 0;
    if (colour == PNG_COLOR_TYPE_PALETTE) png_set_palette_to_rgb(png);
    if (trns) png_set_tRNS_to_alpha(png);
    if (colour == PNG_COLOR_TYPE_GRAY && depth < 8 && !trns) png_set_packing(png); // stored values
    if (depth == 16) png_set_swap(png); // PNG is big-endian; x86-64 is little-endian
    if (interlace != PNG_INTERLACE_NONE) png_set_interlace_handling(png);
    png_read_update_info(png, pinfo);
    info->channels = png_get_channels(png, pinfo);
    info->depth = png_get_bit_depth(png, pinfo);
    if (colour == PNG_COLOR_TYPE_GRAY && depth < 8 && !trns) info->depth = depth; // one byte each
    info->alpha = (colour & PNG_COLOR_MASK_ALPHA) != 0 || trns;
    info->has_phys = png_get_pHYs(png, pinfo, &info->phys_x, &info->phys_y, &info->phys_unit) != 0;
    info->has_offs = png_get_oFFs(png, pinfo, &info->offs_x, &info->offs_y, &info->offs_unit) != 0;
    if (rows) {
        png_read_image(png, rows);
        png_read_end(png, nullptr);
    }
    png_destroy_read_struct(&png, &pinfo, nullptr);
    return true;
}

class PngFile final : public ImageFile {
  public:
    explicit PngFile(const Slice &s) : path_(s.path) {
        FILE *f = std::fopen(s.path.c_str(), "rb");
        if (!f) throw IoError(ISOMEND_IO_ERR_UNREADABLE, s.path + ": cannot open the file");
        bool ok = png_decode(f, &info_, nullptr);
        std::fclose(f);
        if (!ok) throw IoError(ISOMEND_IO_ERR_UNREADABLE, s.path + ": cannot read this file: " + info_.message);
    }

    std::string format() const override { return "png"; }
    bool serves(const Slice &s) const override { return s.path == path_; }
    bool has_subimage(int k) override { return k == 0; }

    ImageHeader header(const Slice &s) override {
        if (s.subimage != 0) throw IoError(ISOMEND_IO_ERR_CORRUPT, slice_name(s) + ": a PNG has one image");
        ImageHeader h;
        h.width = (int)info_.width;
        h.height = (int)info_.height;
        Sample t = info_.depth == 16 ? Sample::U16 : Sample::U8;
        int nc = info_.channels;
        for (int c = 0; c < nc; c++) {
            h.channel_types.push_back(t);
            bool grey = nc <= 2;
            h.channel_names.push_back(grey ? (c == 0 ? "Y" : "A") : std::string(1, "RGBA"[c < 4 ? c : 3]));
        }
        h.bits = info_.depth < 8 ? info_.depth : 0;
        if (info_.has_phys) {
            if (info_.phys_unit == PNG_RESOLUTION_METER) {
                h.xres = (float)(info_.phys_x * 0.0254);
                h.yres = (float)(info_.phys_y * 0.0254);
                h.resolution_unit = "inch";
            } else {
                h.xres = (float)info_.phys_x;
                h.yres = (float)info_.phys_y;
                h.resolution_unit = "none";
            }
        }
        if (info_.has_offs && info_.offs_unit == PNG_OFFSET_PIXEL) {
            h.x = (int)info_.offs_x;
            h.y = (int)info_.offs_y;
        }
        return h;
    }

    void read(const Slice &s, const ImageHeader &h, int cb, int ce, void *dst) override {
        const size_t nc = (size_t)info_.channels;
        const size_t sample = info_.depth == 16 ? 2 : 1;
        const size_t row_bytes = (size_t)info_.width * nc * sample;
        std::vector<unsigned char> pixels(row_bytes * (size_t)info_.height);
        std::vector<unsigned char *> rows((size_t)info_.height);
        for (size_t y = 0; y < rows.size(); y++) rows[y] = pixels.data() + y * row_bytes;
        FILE *f = std::fopen(path_.c_str(), "rb");
        if (!f) throw IoError(ISOMEND_IO_ERR_NOT_FOUND, path_ + ": file not found");
        PngInfo again;
        bool ok = png_decode(f, &again, rows.data());
        std::fclose(f);
        if (!ok || again.width != info_.width || again.height != info_.height || again.channels != info_.channels)
            throw IoError(ISOMEND_IO_ERR_CORRUPT,
                          slice_name(s) + ": corrupt or truncated image data: " +
                              (ok ? std::string("the file changed") : std::string(again.message)));
        const size_t want = (size_t)(ce - cb);
        const size_t n = (size_t)h.width * (size_t)h.height;
        for (size_t i = 0; i < n; i++)
            std::memcpy((char *)dst + i * want * sample, pixels.data() + (i * nc + (size_t)cb) * sample,
                        want * sample);
    }

    void close() override {}

  private:
    std::string path_;
    PngInfo info_{};
};

} // namespace

std::unique_ptr<ImageFile> open_png(const Slice &s) { return std::unique_ptr<ImageFile>(new PngFile(s)); }

} // namespace isomend_io
