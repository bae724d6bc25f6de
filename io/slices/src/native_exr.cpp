// native_exr.cpp - OpenEXR slices with OpenEXR 3 (see native.hpp).
//
// A file is opened once as a MultiPartInputFile; part k is slice k of a
// multi-part stack.  Channels come in OpenImageIO's order (R, G, B, A first,
// then the others in the file's order, which is alphabetical) so that a
// channel index means the same in both backends; half is read as float by
// OpenEXR itself (exact), uint as uint32.  The comments attribute is the
// description, xDensity the resolution in pixels per inch (y: times the
// pixel aspect ratio), as OpenImageIO maps them.  OpenEXR reports damage
// with exceptions: each becomes IoError CORRUPT naming the slice.
#include "native.hpp"

#include <OpenEXR/ImfChannelList.h>
#include <OpenEXR/ImfFloatAttribute.h>
#include <OpenEXR/ImfFrameBuffer.h>
#include <OpenEXR/ImfHeader.h>
#include <OpenEXR/ImfInputPart.h>
#include <OpenEXR/ImfMultiPartInputFile.h>
#include <OpenEXR/ImfPartType.h>
#include <OpenEXR/ImfStringAttribute.h>
#include <OpenEXR/openexr_base.h>

#include <algorithm>

namespace isomend_io {

std::string exr_version() {
    int maj = 0, min = 0, patch = 0;
    const char *extra = nullptr;
    exr_get_library_version(&maj, &min, &patch, &extra);
    return "OpenEXR " + std::to_string(maj) + "." + std::to_string(min) + "." + std::to_string(patch);
}

namespace {

struct Channel {
    std::string name;
    Imf::PixelType type;
};

int rank(const std::string &name) {
    if (name == "R") return 0;
    if (name == "G") return 1;
    if (name == "B") return 2;
    if (name == "A") return 3;
    return 4;
}

class ExrFile final : public ImageFile {
  public:
    explicit ExrFile(const Slice &s) : path_(s.path) {
        try {
            file_.reset(new Imf::MultiPartInputFile(s.path.c_str(), 0));
        } catch (const std::exception &e) {
            throw IoError(ISOMEND_IO_ERR_UNREADABLE, s.path + ": cannot read this file: " + e.what());
        }
    }

    std::string format() const override { return "openexr"; }
    bool serves(const Slice &s) const override { return s.path == path_; }
    bool has_subimage(int k) override { return k >= 0 && k < file_->parts(); }

    ImageHeader header(const Slice &s) override {
        ImageHeader h;
        try {
            const Imf::Header &eh = part_header(s);
            const Imath::Box2i &dw = eh.dataWindow();
            h.x = dw.min.x;
            h.y = dw.min.y;
            h.width = dw.max.x - dw.min.x + 1;
            h.height = dw.max.y - dw.min.y + 1;
            for (const Channel &c : channels(s, eh)) {
                h.channel_names.push_back(c.name);
                h.channel_types.push_back(c.type == Imf::HALF ? Sample::HALF
                                          : c.type == Imf::FLOAT ? Sample::FLOAT
                                                                 : Sample::U32);
            }
            h.bits = 0;
            if (auto *a = eh.findTypedAttribute<Imf::StringAttribute>("comments")) h.description = a->value();
            if (auto *a = eh.findTypedAttribute<Imf::FloatAttribute>("xDensity")) {
                h.xres = a->value();
                h.yres = h.xres * eh.pixelAspectRatio();
                h.resolution_unit = "in";
            }
        } catch (const IoError &) {
            throw;
        } catch (const std::exception &e) {
            throw IoError(ISOMEND_IO_ERR_CORRUPT, slice_name(s) + ": cannot read the header: " + e.what());
        }
        return h;
    }

    void read(const Slice &s, const ImageHeader &h, int cb, int ce, void *dst) override {
        try {
            const Imf::Header &eh = part_header(s);
            std::vector<Channel> all = channels(s, eh);
            const Imath::Box2i &dw = eh.dataWindow();
            const size_t nc = (size_t)(ce - cb);
            const size_t size = 4; // float and uint32: half is read as float
            Imf::FrameBuffer fb;
            for (int c = cb; c < ce; c++) {
                Imf::PixelType t = all[(size_t)c].type == Imf::UINT ? Imf::UINT : Imf::FLOAT;
                char *base = (char *)dst + (size_t)(c - cb) * size;
                fb.insert(all[(size_t)c].name,
                          Imf::Slice::Make(t, base, dw, nc * size, nc * size * (size_t)h.width));
            }
            Imf::InputPart part(*file_, s.subimage);
            part.setFrameBuffer(fb);
            part.readPixels(dw.min.y, dw.max.y);
        } catch (const IoError &) {
            throw;
        } catch (const std::exception &e) {
            throw IoError(ISOMEND_IO_ERR_CORRUPT,
                          slice_name(s) + ": corrupt or truncated image data: " + e.what());
        }
    }

    void close() override {}

  private:
    const Imf::Header &part_header(const Slice &s) {
        if (s.subimage < 0 || s.subimage >= file_->parts())
            throw IoError(ISOMEND_IO_ERR_CORRUPT, slice_name(s) + ": cannot read the header: no such part");
        const Imf::Header &eh = file_->header(s.subimage);
        if (eh.hasType() && (eh.type() == Imf::DEEPSCANLINE || eh.type() == Imf::DEEPTILE))
            throw IoError(ISOMEND_IO_ERR_UNSUPPORTED, slice_name(s) + ": a deep OpenEXR image");
        return eh;
    }

    static std::vector<Channel> channels(const Slice &s, const Imf::Header &eh) {
        std::vector<Channel> out;
        for (auto it = eh.channels().begin(); it != eh.channels().end(); ++it) {
            if (it.channel().xSampling != 1 || it.channel().ySampling != 1)
                throw IoError(ISOMEND_IO_ERR_UNSUPPORTED,
                              slice_name(s) + ": channel " + it.name() + " is subsampled");
            out.push_back({it.name(), it.channel().type});
        }
        std::stable_sort(out.begin(), out.end(),
                         [](const Channel &a, const Channel &b) { return rank(a.name) < rank(b.name); });
        return out;
    }

    std::string path_;
    std::unique_ptr<Imf::MultiPartInputFile> file_;
};

} // namespace

std::unique_ptr<ImageFile> open_exr(const Slice &s) { return std::unique_ptr<ImageFile>(new ExrFile(s)); }

int exr_parts(const std::string &path) {
    try {
        Imf::MultiPartInputFile f(path.c_str(), 0);
        return f.parts();
    } catch (const std::exception &e) {
        throw IoError(ISOMEND_IO_ERR_UNREADABLE, path + ": cannot read this file: " + e.what());
    }
}

} // namespace isomend_io
