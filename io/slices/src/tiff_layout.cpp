// tiff_layout.cpp - the page structure of a TIFF file, read without any image
// library: where every page's IFD is (so that a page can be opened directly
// instead of walking the IFDs before it) and whether a page lacks the
// BitsPerSample tag (OpenImageIO 2.4 misreads such 1-bit pages; image_oiio.cpp).
#include "internal.hpp"

#include <cstdio>

namespace isomend_io {

void locate_tiff_pages(std::vector<Slice> &slices) {
    if (slices.size() < 2) return;
    TiffLayout t = tiff_layout(slices[0].path);
    if (t.ifd.size() != slices.size()) return;
    for (size_t k = 0; k < slices.size(); k++) {
        slices[k].ifd = t.ifd[k];
        slices[k].big_tiff = t.big_tiff;
        slices[k].big_endian = t.big_endian;
        slices[k].no_bits_tag = t.no_bits[k];
    }
}

TiffLayout tiff_layout(const std::string &path) {
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

} // namespace isomend_io
