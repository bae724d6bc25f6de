// image_native.cpp - image.hpp on libtiff, OpenEXR and libpng directly.
//
// The build of libisomend_io that the Blender add-on carries: its
// dependency closure (libtiff and its codecs, OpenEXR, libpng, zlib) is small
// and self-contained enough to bundle next to it and load on any x86-64
// Linux (blender_addon/tools/bundle.py), where OpenImageIO's ~260 libraries
// are not.  It reads TIFF, OpenEXR and PNG; a file is recognised by its
// first bytes, not its name.  Formats that the OpenImageIO build reads and
// this one does not (JPEG, JPEG 2000, BMP, DPX, OpenVDB, ...) are listed in a
// folder like the others and refused with a message naming the format, so
// that a folder of them is not mistaken for an empty one.
#include "native.hpp"

#include <cstdio>
#include <cstring>

namespace isomend_io {

void init_images() {}

std::string image_backend() { return tiff_version() + ", " + exr_version() + ", " + png_version(); }

float half_to_float(uint16_t h) {
    uint32_t sign = (uint32_t)(h & 0x8000u) << 16;
    uint32_t exp = (h >> 10) & 0x1fu, mant = h & 0x3ffu;
    uint32_t bits;
    if (exp == 0) {
        if (mant == 0) {
            bits = sign; // +-0
        } else {           // subnormal: normalise
            int e = -1;
            do {
                e++;
                mant <<= 1;
            } while ((mant & 0x400u) == 0);
            bits = sign | ((uint32_t)(127 - 15 - e) << 23) | ((mant & 0x3ffu) << 13);
        }
    } else if (exp == 31) {
        bits = sign | 0x7f800000u | (mant << 13); // inf, NaN (payload kept)
    } else {
        bits = sign | ((exp + 127 - 15) << 23) | (mant << 13);
    }
    float f;
    std::memcpy(&f, &bits, sizeof f);
    return f;
}

namespace {

enum class Kind { TIFF, EXR, PNG, OTHER };

Kind sniff(const std::string &path) {
    unsigned char b[8] = {};
    FILE *f = std::fopen(path.c_str(), "rb");
    if (!f) return Kind::OTHER;
    size_t n = std::fread(b, 1, sizeof b, f);
    std::fclose(f);
    if (n >= 4 && ((b[0] == 'I' && b[1] == 'I' && (b[2] == 42 || b[2] == 43) && b[3] == 0) ||
                   (b[0] == 'M' && b[1] == 'M' && b[2] == 0 && (b[3] == 42 || b[3] == 43))))
        return Kind::TIFF;
    if (n >= 4 && b[0] == 0x76 && b[1] == 0x2f && b[2] == 0x31 && b[3] == 0x01) return Kind::EXR;
    if (n >= 8 && std::memcmp(b, "\x89PNG\r\n\x1a\n", 8) == 0) return Kind::PNG;
    return Kind::OTHER;
}

// Formats the OpenImageIO build reads and this one does not: listed in a
// folder, refused by name.
struct Unread {
    const char *ext, *name;
};
const Unread kUnread[] = {
    {"jpg", "JPEG"},      {"jpeg", "JPEG"},    {"jpe", "JPEG"},       {"jfif", "JPEG"},
    {"jp2", "JPEG 2000"}, {"j2k", "JPEG 2000"}, {"j2c", "JPEG 2000"}, {"bmp", "BMP"},
    {"dpx", "DPX"},       {"cin", "Cineon"},   {"hdr", "Radiance HDR"}, {"rgbe", "Radiance HDR"},
    {"vdb", "OpenVDB"},   {"gif", "GIF"},      {"webp", "WebP"},      {"tga", "Targa"},
    {"sgi", "SGI"},       {"rgb", "SGI"},      {"pnm", "PNM"},        {"pgm", "PNM"},
    {"ppm", "PNM"},       {"pbm", "PNM"},      {"psd", "Photoshop"},  {"dds", "DDS"},
    {"ico", "ICO"},       {"fits", "FITS"},    {"heic", "HEIF"},      {"avif", "AVIF"},
    {"jxl", "JPEG XL"},   {"tx", "TIFF"},      {"sxr", "OpenEXR"},    {"mxr", "OpenEXR"},
};

const char *unread_format(const std::string &path) {
    std::string e = lower_extension(path);
    for (const Unread &u : kUnread)
        if (e == u.ext) return u.name;
    return nullptr;
}

} // namespace

std::unique_ptr<ImageFile> open_image(const Slice &s) {
    if (!is_regular_file(s.path)) throw IoError(ISOMEND_IO_ERR_NOT_FOUND, s.path + ": file not found");
    switch (sniff(s.path)) {
    case Kind::TIFF: return open_tiff(s);
    case Kind::EXR: return open_exr(s);
    case Kind::PNG: return open_png(s);
    default: break;
    }
    if (const char *name = unread_format(s.path))
        throw IoError(ISOMEND_IO_ERR_UNSUPPORTED,
                      s.path + ": " + name + " images are not read by this build of isomend_io, which "
                               "reads TIFF, OpenEXR and PNG (the portable build that the Blender add-on "
                               "carries); convert the slices to TIFF or PNG, or use the isomend command "
                               "line");
    throw IoError(ISOMEND_IO_ERR_UNREADABLE,
                  s.path + ": cannot read this file: not a TIFF, OpenEXR or PNG image");
}

int count_subimages(const std::string &path) {
    if (!is_regular_file(path)) throw IoError(ISOMEND_IO_ERR_NOT_FOUND, path + ": file not found");
    switch (sniff(path)) {
    case Kind::TIFF: return tiff_pages(path);
    case Kind::EXR: return exr_parts(path);
    default: {
        Slice s;
        s.path = path;
        open_image(s); // throws the reason if it is no image we read
        return 1;
    }
    }
}

std::set<std::string> image_extensions() {
    std::set<std::string> exts = {"tif", "tiff", "exr", "png"};
    for (const Unread &u : kUnread) exts.insert(u.ext);
    return exts;
}

} // namespace isomend_io
