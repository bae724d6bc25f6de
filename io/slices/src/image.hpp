// image.hpp - what the slice-stack importer needs from an image library.
//
// stack.cpp validates and reads stacks through this interface only; one of
// two implementations is linked into each build of libisomend_io:
//   image_oiio.cpp    OpenImageIO (2.4+): every format it reads.  The
//                     library the command line links.
//   image_native.cpp  libtiff, OpenEXR and libpng directly (with
//                     native_tiff.cpp, native_exr.cpp, native_png.cpp):
//                     TIFF, OpenEXR and PNG, and a dependency closure small
//                     enough to bundle, which the Blender add-on carries
//                     (CMake option ISOMEND_ADDON_PORTABLE).
// tests/io runs every stack through both and compares the volumes byte for
// byte.
//
// The contract both keep:
//   - samples are delivered as *stored*: the values the file holds, in their
//     container type (a packed 12-bit sample as 0..4095 in a uint16, a 1-bit
//     one as 0 or 1 in a uint8, signed stays signed); half is widened to
//     float (exact); MinIsWhite TIFF samples are inverted to MinIsBlack and
//     palette images expand to R, G, B (map entries / 257); alpha never
//     multiplies the colour (OpenImageIO's rules where it has them, kept by both);
//   - every decode is checked: damaged data throws IoError CORRUPT naming the
//     slice, never silently delivers zeros;
//   - errors are IoError with the status and a message that names the file
//     (and page); nothing prints.
#ifndef ISOMEND_IO_IMAGE_HPP
#define ISOMEND_IO_IMAGE_HPP

#include <memory>
#include <set>
#include <string>
#include <vector>

#include "internal.hpp"

namespace isomend_io {

// A channel's sample type as stored in the file.
enum class Sample { U8, I8, U16, I16, U32, I32, HALF, FLOAT, DOUBLE, OTHER };

// "uint8", "int16", "half", "float", ... (OpenImageIO's names, used in messages).
const char *sample_name(Sample t);
// Bytes per delivered sample (half is delivered as float: 4).
size_t delivered_size(Sample t);

// One image's (subimage's) header: what the stack checks and the metadata
// spacing comes from.
struct ImageHeader {
    int width = 0, height = 0, depth = 1;
    int x = 0, y = 0;                     // data window origin
    std::vector<std::string> channel_names;
    std::vector<Sample> channel_types;
    int bits = 0;                         // stored bits per sample (12 for packed 12-bit)
    std::string description;              // TIFF ImageDescription / EXR comments, or ""
    float xres = 0, yres = 0;             // pixels per resolution_unit (0: not given)
    std::string resolution_unit;          // "in", "inch", "cm", "mm", "none" or ""
    int nchannels() const { return (int)channel_types.size(); }
    int channel_index(const std::string &name) const;
};

// An open image file.  One thread at a time; files of different slices may be
// read by different threads at once.
class ImageFile {
  public:
    virtual ~ImageFile() = default;
    // The format's name: "tiff", "openexr", "png", ... (isomend_io_format()).
    virtual std::string format() const = 0;
    // Whether this open file can give slice s (the same file; a backend may
    // need a fresh open for a page it reaches directly).
    virtual bool serves(const Slice &s) const = 0;
    // Whether the file has a subimage (page, part) k.
    virtual bool has_subimage(int k) = 0;
    // The header of slice s (its page); throws IoError CORRUPT if unreadable.
    virtual ImageHeader header(const Slice &s) = 0;
    // Reads channels [cb, ce) of slice s, whose header is h, into dst: packed,
    // channel fastest, rows top to bottom, in the delivered types.
    virtual void read(const Slice &s, const ImageHeader &h, int cb, int ce, void *dst) = 0;
    // Closes the file, reporting an error the library deferred.
    virtual void close() = 0;
};

// Opens slice s's file: IoError NOT_FOUND if it does not exist, UNREADABLE if
// it is no image this backend reads, UNSUPPORTED naming the format if it is
// one the other backend reads.
std::unique_ptr<ImageFile> open_image(const Slice &s);

// Counts the subimages (pages, parts) of one file (1 for an ordinary image).
int count_subimages(const std::string &path);

// The file extensions (lower case, no dot) a folder listing takes as images.
std::set<std::string> image_extensions();

// The image libraries and their versions, e.g. "OpenImageIO 2.4.7".
std::string image_backend();

// One-time set-up of the image libraries (thread-safe, idempotent).
void init_images();

} // namespace isomend_io

#endif
