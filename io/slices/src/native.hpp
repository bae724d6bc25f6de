// native.hpp - the formats of image_native.cpp, one file each.
//
//   native_tiff.cpp  libtiff 4.5+: every TIFF it decodes (8/16/32/64-bit,
//                    packed 1..15-bit, signed, float and half, strips and
//                    tiles, contiguous and separate planes, every codec
//                    libtiff was built with, multi-page, BigTIFF); palette
//                    and JPEG-YCbCr as R, G, B; MinIsWhite inverted;
//   native_exr.cpp   OpenEXR 3: half, float and uint channels, scanline and
//                    tiled, multi-part (parts are slices);
//   native_png.cpp   libpng 1.6: grey, grey+alpha, RGB, RGBA, palette, 1..16
//                    bits, interlaced.
// Each keeps image.hpp's contract and follows OpenImageIO's reading rules
// where it has one (channel names and order, the metadata it maps to
// resolution and description), so that both backends give the same volume;
// tests/io compares them.
#ifndef ISOMEND_IO_NATIVE_HPP
#define ISOMEND_IO_NATIVE_HPP

#include "image.hpp"

namespace isomend_io {

std::unique_ptr<ImageFile> open_tiff(const Slice &s);
int tiff_pages(const std::string &path);
std::string tiff_version();

std::unique_ptr<ImageFile> open_exr(const Slice &s);
int exr_parts(const std::string &path);
std::string exr_version();

std::unique_ptr<ImageFile> open_png(const Slice &s);
std::string png_version();

// Bit-exact half -> float.
float half_to_float(uint16_t h);

// Sample k of a row of packed samples of `bits` bits each, most significant
// bit first (TIFF and PNG), for bits 1..16.
inline uint32_t packed_sample(const unsigned char *row, size_t k, int bits) {
    size_t bit = k * (size_t)bits;
    uint32_t v = 0;
    int have = 0;
    size_t byte = bit >> 3;
    int skip = (int)(bit & 7);
    // gather up to 24 bits, then keep `bits` of them
    while (have < skip + bits) {
        v = (v << 8) | row[byte++];
        have += 8;
    }
    return (v >> (have - skip - bits)) & ((1u << bits) - 1u);
}

} // namespace isomend_io

#endif
