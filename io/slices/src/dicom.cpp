// dicom.cpp - DICOM series with GDCM 3.0: find, group, sort, validate, decode.
//
// The passes, in order (isomend_io.h, "DICOM", is the contract):
//   1. candidates: a folder's files whose content starts with the DICOM
//      preamble ("DICM" at byte 128), a DICOMDIR's referenced images, a list
//      of files, or one multi-frame file;
//   2. headers: every candidate is parsed up to its Pixel Data (gdcm::Reader::
//      ReadUpToTag, worker threads); objects without Rows/Columns are not
//      images (reports, presentation states, RT structures) and are counted;
//   3. series: images grouped by Series Instance UID, listed by Series
//      Number then UID; one is chosen (the only one, or the caller's UID or
//      1-based position);
//   4. geometry: one frame per single-frame file, or the frames of an
//      enhanced file (per-frame functional groups override the shared ones);
//      checks that size, pixel format, orientation and pixel spacing agree;
//      sorts by position along the normal n = row x column; refuses
//      duplicates; places every frame at its own origin in the series'
//      frame (row . P, column . P, n . P): a series within 1e-4 pixel of
//      evenly spaced on one line is a uniform grid as before, any other
//      (uneven gaps, positions rounded by the scanner, a missing slice, a
//      spacing change, a gantry tilt's shear) keeps its table of slice
//      origins, which the core meshes where the slices are (geometry.cpp;
//      a one-line warning for gaps that vary by more than 1%);
//   5. type: the stored range Bits Stored allows, through MONOCHROME1
//      inversion and every frame's rescale, gives the delivered type (no
//      value can clip);
//   6. decoding: gdcm::ImageReader per file (any transfer syntax GDCM
//      decodes), on worker threads one file each, then each frame converted
//      (mask to Bits Stored, sign extension, inversion, rescale) into its
//      sorted slot.
// Errors are IoError naming the file; api.cpp turns them into statuses.
// Tolerances (docs/dicom.md says why): orientation 1e-4 per cosine; a
// uniform grid when every slice origin is within 1e-4 of the smaller pixel
// spacing of the evenly spaced line; duplicates closer than a hundredth of it.
#include "dicom.hpp"
#include "internal.hpp"
#include "parallel_slices.hpp"

#include <algorithm>
#include <charconv>
#include <cmath>
#include <cstdio>
#include <cstring>
#include <map>
#include <memory>
#include <set>
#include <mutex>

#include <dirent.h>
#include <sys/stat.h>

#include <gdcmAttribute.h>
#include <gdcmDataSet.h>
#include <gdcmFile.h>
#include <gdcmImage.h>
#include <gdcmImageReader.h>
#include <gdcmReader.h>
#include <gdcmSequenceOfItems.h>
#include <gdcmTag.h>
#include <gdcmTrace.h>
#include <gdcmTransferSyntax.h>
#include <gdcmUIDs.h>

namespace isomend_io {

namespace {

constexpr double kOrientationTolerance = 1e-4;
constexpr double kUniformTolerance = 1e-4;   // of the smaller pixel spacing
constexpr double kDuplicateTolerance = 0.01; // of the smaller pixel spacing

const gdcm::Tag kPixelData(0x7fe0, 0x0010);

// GDCM reports warnings and errors on std::cerr; the library never prints,
// and every failure reaches the caller as a status and message instead.
// Process-wide in GDCM, set once (like OpenImageIO's attributes).
void quiet_gdcm() {
    static std::once_flag once;
    std::call_once(once, [] {
        gdcm::Trace::DebugOff();
        gdcm::Trace::WarningOff();
        gdcm::Trace::ErrorOff();
    });
}

uint64_t file_size(const std::string &path) {
    struct stat st;
    return ::stat(path.c_str(), &st) == 0 ? (uint64_t)st.st_size : 0;
}

// ---------------------------------------------------------------- values

std::string trim(std::string s) {
    while (!s.empty() && (s.back() == ' ' || s.back() == '\0')) s.pop_back();
    size_t b = 0;
    while (b < s.size() && s[b] == ' ') b++;
    return s.substr(b);
}

std::string text_of(const gdcm::DataSet &ds, uint16_t g, uint16_t e) {
    gdcm::Tag t(g, e);
    if (!ds.FindDataElement(t)) return "";
    const gdcm::ByteValue *bv = ds.GetDataElement(t).GetByteValue();
    if (!bv || !bv->GetPointer()) return "";
    return trim(std::string(bv->GetPointer(), bv->GetLength()));
}

// Backslash-separated decimal strings (DS, IS), parsed without the C locale
// (a host such as Blender or MeshLab may have set a decimal comma).
int numbers_of(const gdcm::DataSet &ds, uint16_t g, uint16_t e, double *out, int n) {
    std::string s = text_of(ds, g, e);
    int got = 0;
    size_t i = 0;
    while (got < n && i <= s.size()) {
        size_t j = s.find('\\', i);
        if (j == std::string::npos) j = s.size();
        std::string item = trim(s.substr(i, j - i));
        size_t b = 0;
        if (!item.empty() && item[0] == '+') b = 1;
        double v = 0;
        auto r = std::from_chars(item.data() + b, item.data() + item.size(), v);
        if (item.size() <= b || r.ec != std::errc() || r.ptr != item.data() + item.size() || !std::isfinite(v))
            return -1;
        out[got++] = v;
        i = j + 1;
    }
    return got;
}

bool number_of(const gdcm::DataSet &ds, uint16_t g, uint16_t e, double *v) {
    return numbers_of(ds, g, e, v, 1) == 1;
}

// An unsigned short (US) element, byte order handled by gdcm::Attribute.
template <uint16_t G, uint16_t E> int us_of(const gdcm::DataSet &ds, int fallback) {
    gdcm::Attribute<G, E> a;
    if (!ds.FindDataElement(a.GetTag()) || ds.GetDataElement(a.GetTag()).IsEmpty()) return fallback;
    a.SetFromDataSet(ds);
    return (int)a.GetValue();
}

// The first item of a sequence, or nullptr.
const gdcm::DataSet *first_item(const gdcm::DataSet &ds, uint16_t g, uint16_t e,
                                gdcm::SmartPointer<gdcm::SequenceOfItems> &keep) {
    gdcm::Tag t(g, e);
    if (!ds.FindDataElement(t)) return nullptr;
    keep = ds.GetDataElement(t).GetValueAsSQ();
    if (!keep || keep->GetNumberOfItems() < 1) return nullptr;
    return &keep->GetItem(1).GetNestedDataSet();
}

double dot(const double *a, const double *b) { return a[0] * b[0] + a[1] * b[1] + a[2] * b[2]; }

// v with `digits` significant digits (%g)
std::string num(double v, int digits = 6) {
    char b[64];
    std::snprintf(b, sizeof b, "%.*g", digits, v);
    return b;
}

std::string mm(double v) { return num(v) + " mm"; }

// ---------------------------------------------------------------- headers

struct FrameGeometry {
    bool has_position = false, has_orientation = false, has_spacing = false;
    double position[3] = {0, 0, 0};
    double orientation[6] = {0, 0, 0, 0, 0, 0};
    double spacing[2] = {0, 0}; // Pixel Spacing: row spacing, column spacing
    double slope = 1, intercept = 0;
    std::string rescale_type;
};

struct Header {
    std::string path;
    bool parsed = false, image = false, dicomdir = false;
    std::string sop_class, modality, series_uid, description, photometric, ts_uid, ts_name;
    int64_t series_number = -1;
    int rows = 0, columns = 0, samples = 1, bits_allocated = 0, bits_stored = 0, high_bit = 0;
    int pixel_representation = 0;
    int64_t frames = 1;
    bool enhanced = false;
    std::vector<FrameGeometry> geometry; // one per frame
};

// Reads what geometry a data set (the file's top level, or a functional
// group item) says into g; absent elements leave g as it was.
void read_geometry(const gdcm::DataSet &ds, FrameGeometry &g) {
    if (numbers_of(ds, 0x0020, 0x0032, g.position, 3) == 3) g.has_position = true;
    if (numbers_of(ds, 0x0020, 0x0037, g.orientation, 6) == 6) g.has_orientation = true;
    if (numbers_of(ds, 0x0028, 0x0030, g.spacing, 2) == 2) g.has_spacing = true;
    double v;
    if (number_of(ds, 0x0028, 0x1053, &v)) g.slope = v;
    if (number_of(ds, 0x0028, 0x1052, &v)) g.intercept = v;
    std::string rt = text_of(ds, 0x0028, 0x1054);
    if (!rt.empty()) g.rescale_type = rt;
}

// A functional group item (shared or per frame) into g.
void read_functional_groups(const gdcm::DataSet &item, FrameGeometry &g) {
    gdcm::SmartPointer<gdcm::SequenceOfItems> keep;
    if (const gdcm::DataSet *d = first_item(item, 0x0020, 0x9113, keep)) read_geometry(*d, g); // Plane Position
    if (const gdcm::DataSet *d = first_item(item, 0x0020, 0x9116, keep)) read_geometry(*d, g); // Plane Orientation
    if (const gdcm::DataSet *d = first_item(item, 0x0028, 0x9110, keep)) read_geometry(*d, g); // Pixel Measures
    if (const gdcm::DataSet *d = first_item(item, 0x0028, 0x9145, keep)) read_geometry(*d, g); // Pixel Value Transformation
}

void read_header(Header &h) {
    quiet_gdcm();
    gdcm::Reader r;
    r.SetFileName(h.path.c_str());
    // Up to the Pixel Data element, whose value is skipped (not read): the
    // stream then stands at the start of the value.
    if (!r.ReadUpToTag(kPixelData, std::set<gdcm::Tag>{kPixelData}))
        throw IoError(ISOMEND_IO_ERR_CORRUPT, h.path + ": not a readable DICOM file (GDCM cannot parse its header; "
                                                       "truncated or corrupt)");
    const gdcm::File &f = r.GetFile();
    const gdcm::DataSet &meta = f.GetHeader();
    const gdcm::DataSet &ds = f.GetDataSet();
    h.parsed = true;
    h.sop_class = text_of(meta, 0x0002, 0x0002);
    if (h.sop_class.empty()) h.sop_class = text_of(ds, 0x0008, 0x0016);
    if (h.sop_class == "1.2.840.10008.1.3.10") {
        h.dicomdir = true;
        return;
    }
    h.ts_uid = text_of(meta, 0x0002, 0x0010);
    const gdcm::TransferSyntax &ts = f.GetHeader().GetDataSetTransferSyntax();
    gdcm::UIDs names;
    h.ts_name = names.SetFromUID(h.ts_uid.c_str()) && names.GetName() ? names.GetName() : h.ts_uid;
    if (h.ts_name.find(':') != std::string::npos) h.ts_name.erase(h.ts_name.find(':')); // ": Default Transfer Syntax ...
    h.modality = text_of(ds, 0x0008, 0x0060);
    h.series_uid = text_of(ds, 0x0020, 0x000e);
    h.description = text_of(ds, 0x0008, 0x103e);
    double v;
    if (number_of(ds, 0x0020, 0x0011, &v)) h.series_number = (int64_t)v;
    h.rows = us_of<0x0028, 0x0010>(ds, 0);
    h.columns = us_of<0x0028, 0x0011>(ds, 0);
    h.image = h.rows > 0 && h.columns > 0;
    if (!h.image) return;
    h.samples = us_of<0x0028, 0x0002>(ds, 1);
    h.photometric = text_of(ds, 0x0028, 0x0004);
    h.bits_allocated = us_of<0x0028, 0x0100>(ds, 0);
    h.bits_stored = us_of<0x0028, 0x0101>(ds, h.bits_allocated);
    h.high_bit = us_of<0x0028, 0x0102>(ds, h.bits_stored - 1);
    h.pixel_representation = us_of<0x0028, 0x0103>(ds, 0);
    if (number_of(ds, 0x0028, 0x0008, &v)) h.frames = (int64_t)v;
    if (h.frames < 1) h.frames = 1;
    FrameGeometry top;
    read_geometry(ds, top);
    h.enhanced = ds.FindDataElement(gdcm::Tag(0x5200, 0x9230)) || ds.FindDataElement(gdcm::Tag(0x5200, 0x9229));
    // Uncompressed pixel data cut short: GDCM reads what is there ("use file
    // at own risk") and pads, so the file's length is checked here, at open.
    if (!ts.IsEncapsulated() && h.bits_allocated > 0) {
        uint64_t need = (uint64_t)h.rows * (uint64_t)h.columns * (uint64_t)h.frames * (uint64_t)h.samples *
                        (uint64_t)h.bits_allocated / 8;
        uint64_t at = (uint64_t)r.GetStreamCurrentPosition(), size = file_size(h.path);
        if (at + need > size)
            throw IoError(ISOMEND_IO_ERR_CORRUPT,
                          h.path + ": truncated: the pixel data need " + std::to_string(need) + " bytes, the file has " +
                              std::to_string(size > at ? size - at : 0) + " after the header");
    }
    if (!h.enhanced) {
        h.geometry.assign((size_t)h.frames, top);
        return;
    }
    FrameGeometry shared = top;
    gdcm::SmartPointer<gdcm::SequenceOfItems> keep;
    if (const gdcm::DataSet *s = first_item(ds, 0x5200, 0x9229, keep)) read_functional_groups(*s, shared);
    h.geometry.assign((size_t)h.frames, shared);
    gdcm::Tag per(0x5200, 0x9230);
    if (ds.FindDataElement(per)) {
        gdcm::SmartPointer<gdcm::SequenceOfItems> sq = ds.GetDataElement(per).GetValueAsSQ();
        if (!sq || (int64_t)sq->GetNumberOfItems() != h.frames)
            throw IoError(ISOMEND_IO_ERR_CORRUPT,
                          h.path + ": " + std::to_string(sq ? sq->GetNumberOfItems() : 0) +
                              " per-frame functional groups for " + std::to_string(h.frames) + " frames");
        for (int64_t k = 0; k < h.frames; k++)
            read_functional_groups(sq->GetItem((size_t)k + 1).GetNestedDataSet(), h.geometry[(size_t)k]);
    }
}

// The worker pool of both DICOM passes (headers, images), one task per file:
// progress is reported at once, and any failure ranks as the file it came from.
void parallel_for(int64_t n, int threads, const std::function<void(int64_t)> &fn,
                  const std::function<bool(double)> &progress, const char *what) {
    SlicePool pool{what, std::string("cannot start threads for ") + what, true, true};
    read_slices_parallel(
        n, threads, [&](int64_t k, std::vector<char> &) { fn(k); }, progress, pool);
}

// ---------------------------------------------------------------- type

bool is_integer(double v) { return std::isfinite(v) && v == std::floor(v) && std::fabs(v) < 9e15; }

isomend_type integer_type_for(int64_t lo, int64_t hi) {
    if (lo >= 0 && hi <= 255) return ISOMEND_U8;
    if (lo >= -32768 && hi <= 32767) return ISOMEND_I16;
    if (lo >= 0 && hi <= 65535) return ISOMEND_U16;
    if (lo >= INT32_MIN && hi <= INT32_MAX) return ISOMEND_I32;
    return ISOMEND_F64;
}

void choose_type(DicomSeries &s) {
    const int b = s.bits_stored;
    s.smin = s.pixel_signed ? -(int64_t(1) << (b - 1)) : 0;
    s.smax = s.pixel_signed ? (int64_t(1) << (b - 1)) - 1 : (int64_t(1) << b) - 1;
    s.rescaled = false;
    s.integer_rescale = true;
    int64_t lo = INT64_MAX, hi = INT64_MIN;
    for (const auto &f : s.frames) {
        if (f.slope != 1.0 || f.intercept != 0.0) s.rescaled = true;
        if (!is_integer(f.slope) || !is_integer(f.intercept)) s.integer_rescale = false;
    }
    if (!s.rescaled) {
        if (s.bits_allocated <= 8) s.type = s.pixel_signed ? ISOMEND_I8 : ISOMEND_U8;
        else if (s.bits_allocated <= 16) s.type = s.pixel_signed ? ISOMEND_I16 : ISOMEND_U16;
        else s.type = s.pixel_signed || s.bits_stored < 32 ? ISOMEND_I32 : ISOMEND_F64;
        return;
    }
    if (!s.integer_rescale) {
        s.type = s.bits_stored > 16 ? ISOMEND_F64 : ISOMEND_F32;
        return;
    }
    for (const auto &f : s.frames) {
        double a = f.slope * (double)s.smin + f.intercept, c = f.slope * (double)s.smax + f.intercept;
        double l = std::min(a, c), h = std::max(a, c);
        if (!(std::fabs(l) < 9e15 && std::fabs(h) < 9e15)) {
            s.type = ISOMEND_F64;
            return;
        }
        lo = std::min(lo, (int64_t)l);
        hi = std::max(hi, (int64_t)h);
    }
    s.type = integer_type_for(lo, hi);
}

// ---------------------------------------------------------------- folders

bool read_magic(const std::string &path) {
    FILE *f = std::fopen(path.c_str(), "rb");
    if (!f) return false;
    unsigned char b[132];
    size_t n = std::fread(b, 1, sizeof b, f);
    std::fclose(f);
    return n == sizeof b && std::memcmp(b + 128, "DICM", 4) == 0;
}

std::string upper_name(const std::string &path) {
    size_t slash = path.find_last_of('/');
    std::string n = slash == std::string::npos ? path : path.substr(slash + 1);
    for (char &c : n) c = (char)std::toupper((unsigned char)c);
    return n;
}

void list_entries(const std::string &dir, std::vector<std::string> &files, std::vector<std::string> &dirs) {
    DIR *d = ::opendir(dir.c_str());
    if (!d) throw IoError(ISOMEND_IO_ERR_NOT_FOUND, dir + ": cannot open folder: " + std::strerror(errno));
    std::string base = dir;
    if (!base.empty() && base.back() != '/') base += '/';
    while (struct dirent *e = ::readdir(d)) {
        if (e->d_name[0] == '.') continue;
        std::string full = base + e->d_name;
        struct stat st;
        if (::stat(full.c_str(), &st) != 0) continue;
        if (S_ISREG(st.st_mode)) files.push_back(full);
        else if (S_ISDIR(st.st_mode)) dirs.push_back(full);
    }
    ::closedir(d);
    std::sort(files.begin(), files.end(), natural_less);
    std::sort(dirs.begin(), dirs.end(), natural_less);
}

void collect(const std::string &dir, int depth, DicomFiles &out) {
    std::vector<std::string> files, dirs;
    list_entries(dir, files, dirs);
    for (const auto &f : files) {
        if (read_magic(f)) out.files.push_back(f);
        else out.non_dicom++;
    }
    if (depth > 0)
        for (const auto &d : dirs) collect(d, depth - 1, out);
}

// A DICOMDIR's Referenced File ID ("DIR1\IM000001") relative to its folder;
// media written in upper case are often read back in lower case, so each
// component is also matched case-insensitively.
std::string resolve_reference(const std::string &base, const std::string &id) {
    std::string path = base;
    size_t i = 0;
    while (i <= id.size()) {
        size_t j = id.find('\\', i);
        if (j == std::string::npos) j = id.size();
        std::string part = trim(id.substr(i, j - i));
        i = j + 1;
        if (part.empty()) continue;
        std::string exact = path + "/" + part;
        struct stat st;
        if (::stat(exact.c_str(), &st) == 0) {
            path = exact;
            continue;
        }
        std::string found;
        if (DIR *d = ::opendir(path.c_str())) {
            std::string up = upper_name(part);
            while (struct dirent *e = ::readdir(d))
                if (upper_name(e->d_name) == up) {
                    found = path + "/" + e->d_name;
                    break;
                }
            ::closedir(d);
        }
        path = found.empty() ? exact : found;
    }
    return path;
}

} // namespace

bool is_dicom_file(const std::string &path) { return read_magic(path); }

bool dicomdir_files(const std::string &path, DicomFiles &out) {
    quiet_gdcm();
    gdcm::Reader r;
    r.SetFileName(path.c_str());
    bool named = upper_name(path) == "DICOMDIR";
    if (!r.Read()) {
        if (named)
            throw IoError(ISOMEND_IO_ERR_CORRUPT, path + ": not a readable DICOMDIR (GDCM cannot parse it)");
        return false;
    }
    const gdcm::File &f = r.GetFile();
    std::string sop = text_of(f.GetHeader(), 0x0002, 0x0002);
    if (sop != "1.2.840.10008.1.3.10" && !named) return false;
    const gdcm::DataSet &ds = f.GetDataSet();
    gdcm::Tag records(0x0004, 0x1220);
    std::string base = path.find('/') == std::string::npos ? "." : path.substr(0, path.find_last_of('/'));
    if (base.empty()) base = "/";
    out.label = path;
    if (ds.FindDataElement(records)) {
        gdcm::SmartPointer<gdcm::SequenceOfItems> sq = ds.GetDataElement(records).GetValueAsSQ();
        for (size_t i = 1; sq && i <= sq->GetNumberOfItems(); i++) {
            const gdcm::DataSet &item = sq->GetItem(i).GetNestedDataSet();
            std::string id = text_of(item, 0x0004, 0x1500);
            if (id.empty()) continue;
            std::string type = text_of(item, 0x0004, 0x1430);
            std::string file = resolve_reference(base, id);
            struct stat st;
            if (::stat(file.c_str(), &st) != 0 || !S_ISREG(st.st_mode))
                throw IoError(ISOMEND_IO_ERR_NOT_FOUND,
                              file + ": referenced by " + path + " (" + type + " record) but not found");
            if (type == "IMAGE") out.files.push_back(file); // other records (reports, ...) are not read
        }
    }
    if (out.files.empty())
        throw IoError(ISOMEND_IO_ERR_NOT_FOUND, path + ": the DICOMDIR references no image");
    return true;
}

bool dicom_folder_files(const std::string &dir, bool recursive, DicomFiles &out) {
    out = DicomFiles{};
    out.label = dir;
    std::vector<std::string> files, dirs;
    list_entries(dir, files, dirs);
    for (const auto &f : files)
        if (upper_name(f) == "DICOMDIR") {
            DicomFiles d;
            if (dicomdir_files(f, d)) {
                out.files = d.files;
                out.non_dicom = (int64_t)files.size() - 1; // the folder's other files
                return true;
            }
        }
    collect(dir, recursive ? 16 : 0, out);
    return !out.files.empty();
}

size_t DicomSeries::sample_size() const { return isomend_type_size(type); }

void dicom_open(const DicomFiles &in, const DicomOptions &o, DicomSeries &out,
                const std::function<void(double)> &progress) {
    out = DicomSeries{};
    out.axes = o.axes;
    out.non_dicom = in.non_dicom;
    // 2. headers
    std::vector<Header> headers(in.files.size());
    for (size_t i = 0; i < in.files.size(); i++) headers[i].path = in.files[i];
    parallel_for(
        (int64_t)headers.size(), o.threads,
        [&](int64_t k) {
            Header &h = headers[(size_t)k];
            if (in.explicit_list && !read_magic(h.path)) {
                struct stat st;
                if (::stat(h.path.c_str(), &st) != 0)
                    throw IoError(ISOMEND_IO_ERR_NOT_FOUND, h.path + ": file not found");
                throw IoError(ISOMEND_IO_ERR_UNREADABLE,
                              h.path + ": not a DICOM file (no \"DICM\" after the 128-byte preamble)");
            }
            read_header(h);
        },
        [&](double f) {
            if (progress) progress(f);
            return false;
        },
        "reading DICOM headers");
    // 3. series
    std::map<std::string, std::vector<size_t>> by_uid;
    for (size_t i = 0; i < headers.size(); i++) {
        const Header &h = headers[i];
        if (h.dicomdir) {
            out.non_image++;
            continue;
        }
        if (!h.image) {
            out.non_image++;
            continue;
        }
        by_uid[h.series_uid].push_back(i);
    }
    if (by_uid.empty())
        throw IoError(ISOMEND_IO_ERR_NOT_FOUND,
                      in.label + ": no DICOM image (" + std::to_string(out.non_image) +
                          " DICOM objects without pixel data, " + std::to_string(out.non_dicom) +
                          " files that are not DICOM)");
    std::vector<std::pair<std::string, std::vector<size_t>>> groups(by_uid.begin(), by_uid.end());
    std::stable_sort(groups.begin(), groups.end(), [&](const auto &a, const auto &b) {
        int64_t na = headers[a.second[0]].series_number, nb = headers[b.second[0]].series_number;
        if (na != nb) return na < nb;
        return a.first < b.first;
    });
    for (const auto &g : groups) {
        const Header &h = headers[g.second[0]];
        DicomSeriesEntry e;
        e.uid = g.first;
        e.description = h.description;
        e.modality = h.modality;
        e.number = h.series_number;
        e.files = (int64_t)g.second.size();
        for (size_t i : g.second) e.images += headers[i].frames;
        e.columns = h.columns;
        e.rows = h.rows;
        out.series.push_back(e);
    }
    auto list_text = [&] {
        std::string t;
        for (size_t i = 0; i < out.series.size(); i++) {
            const auto &e = out.series[i];
            t += "\n  " + std::to_string(i + 1) + ": " + (e.modality.empty() ? "?" : e.modality) + " \"" +
                 e.description + "\"" + (e.number >= 0 ? ", series number " + std::to_string(e.number) : "") +
                 ", " + std::to_string(e.columns) + "x" + std::to_string(e.rows) + ", " +
                 std::to_string(e.images) + " images in " + std::to_string(e.files) + " files, UID " +
                 (e.uid.empty() ? "(none)" : e.uid);
        }
        return t;
    };
    int64_t chosen = -1;
    if (o.series.empty()) {
        if (groups.size() > 1)
            throw IoError(ISOMEND_IO_ERR_SERIES,
                          in.label + ": " + std::to_string(groups.size()) +
                              " DICOM series; choose one with --series N or --series UID:" + list_text());
        chosen = 0;
    } else if (o.series.find_first_not_of("0123456789") == std::string::npos) {
        long long n = std::strtoll(o.series.c_str(), nullptr, 10);
        if (n < 1 || n > (long long)groups.size())
            throw IoError(ISOMEND_IO_ERR_SERIES, in.label + ": no series " + o.series + "; there " +
                                                     (groups.size() == 1 ? "is 1" : "are " + std::to_string(groups.size())) +
                                                     ":" + list_text());
        chosen = n - 1;
    } else {
        for (size_t i = 0; i < groups.size(); i++)
            if (groups[i].first == o.series) chosen = (int64_t)i;
        if (chosen < 0)
            throw IoError(ISOMEND_IO_ERR_SERIES,
                          in.label + ": no series with UID " + o.series + "; the series are:" + list_text());
    }
    out.chosen = chosen;
    for (size_t i = 0; i < groups.size(); i++)
        if ((int64_t)i != chosen) out.other_series += (int64_t)groups[i].second.size();

    // 4. geometry
    const std::vector<size_t> &members = groups[(size_t)chosen].second;
    const Header &h0 = headers[members[0]];
    out.uid = groups[(size_t)chosen].first;
    out.modality = h0.modality;
    out.description = h0.description;
    out.ts_uid = h0.ts_uid;
    out.ts_name = h0.ts_name;
    out.photometric = h0.photometric;
    out.files = (int64_t)members.size();
    out.width = h0.columns;
    out.height = h0.rows;
    out.bits_allocated = h0.bits_allocated;
    out.bits_stored = h0.bits_stored;
    out.high_bit = h0.high_bit;
    out.pixel_signed = h0.pixel_representation == 1;
    out.monochrome1 = h0.photometric == "MONOCHROME1";
    if (h0.samples != 1 || (h0.photometric != "MONOCHROME1" && h0.photometric != "MONOCHROME2"))
        throw IoError(ISOMEND_IO_ERR_UNSUPPORTED,
                      h0.path + ": a colour image (" + std::to_string(h0.samples) + " samples per pixel, " +
                          (h0.photometric.empty() ? "no photometric interpretation" : h0.photometric) +
                          "); only greyscale (MONOCHROME1/2) series are volumes");
    if (h0.bits_allocated != 8 && h0.bits_allocated != 16 && h0.bits_allocated != 32)
        throw IoError(ISOMEND_IO_ERR_UNSUPPORTED,
                      h0.path + ": " + std::to_string(h0.bits_allocated) + " bits allocated per sample " +
                          "(8, 16 or 32 are supported)");
    if (h0.bits_stored < 1 || h0.bits_stored > h0.bits_allocated || h0.high_bit < h0.bits_stored - 1 ||
        h0.high_bit >= h0.bits_allocated)
        throw IoError(ISOMEND_IO_ERR_CORRUPT, h0.path + ": inconsistent Bits Stored " + std::to_string(h0.bits_stored) +
                                                  " / High Bit " + std::to_string(h0.high_bit) + " for " +
                                                  std::to_string(h0.bits_allocated) + " bits allocated");
    const FrameGeometry &g0 = h0.geometry[0];
    if (!g0.has_orientation)
        throw IoError(ISOMEND_IO_ERR_UNSUPPORTED, h0.path + ": no Image Orientation (Patient) (0020,0037): "
                                                            "the slices cannot be placed");
    if (!g0.has_spacing && !o.spacing_given)
        throw IoError(ISOMEND_IO_ERR_UNSUPPORTED,
                      h0.path + ": no Pixel Spacing (0028,0030); give the spacing (--spacing DX,DY,DZ)");
    std::string differs = " differs from the first image's (" + h0.path + ")";
    for (size_t m : members) {
        const Header &h = headers[m];
        if (h.rows != h0.rows || h.columns != h0.columns)
            throw IoError(ISOMEND_IO_ERR_MISMATCH, h.path + ": size " + std::to_string(h.columns) + "x" +
                                                       std::to_string(h.rows) + differs + " " +
                                                       std::to_string(h0.columns) + "x" + std::to_string(h0.rows));
        if (h.bits_allocated != h0.bits_allocated || h.bits_stored != h0.bits_stored ||
            h.high_bit != h0.high_bit || h.pixel_representation != h0.pixel_representation)
            throw IoError(ISOMEND_IO_ERR_MISMATCH,
                          h.path + ": pixel format (" + std::to_string(h.bits_stored) + " of " +
                              std::to_string(h.bits_allocated) + " bits, " +
                              (h.pixel_representation ? "signed" : "unsigned") + ")" + differs + " (" +
                              std::to_string(h0.bits_stored) + " of " + std::to_string(h0.bits_allocated) +
                              " bits, " + (h0.pixel_representation ? "signed" : "unsigned") + ")");
        if (h.samples != h0.samples || h.photometric != h0.photometric)
            throw IoError(ISOMEND_IO_ERR_MISMATCH, h.path + ": photometric interpretation " + h.photometric + differs +
                                                       " " + h0.photometric);
        for (int64_t k = 0; k < h.frames; k++) {
            const FrameGeometry &g = h.geometry[(size_t)k];
            std::string name = h.path + (h.frames > 1 ? " (frame " + std::to_string(k + 1) + ")" : "");
            if (!g.has_position)
                throw IoError(ISOMEND_IO_ERR_UNSUPPORTED,
                              name + ": no Image Position (Patient) (0020,0032): the slice cannot be placed");
            if (!g.has_orientation)
                throw IoError(ISOMEND_IO_ERR_UNSUPPORTED, name + ": no Image Orientation (Patient) (0020,0037)");
            for (int c = 0; c < 6; c++)
                if (std::fabs(g.orientation[c] - g0.orientation[c]) > kOrientationTolerance) {
                    char b[256];
                    std::snprintf(b, sizeof b, "%g\\%g\\%g\\%g\\%g\\%g", g.orientation[0], g.orientation[1],
                                  g.orientation[2], g.orientation[3], g.orientation[4], g.orientation[5]);
                    char b0[256];
                    std::snprintf(b0, sizeof b0, "%g\\%g\\%g\\%g\\%g\\%g", g0.orientation[0], g0.orientation[1],
                                  g0.orientation[2], g0.orientation[3], g0.orientation[4], g0.orientation[5]);
                    throw IoError(ISOMEND_IO_ERR_MISMATCH, name + ": Image Orientation (Patient) " + b + differs +
                                                               " " + b0 + " (a localizer, or another stack?)");
                }
            if (!o.spacing_given) {
                if (!g.has_spacing) throw IoError(ISOMEND_IO_ERR_UNSUPPORTED, name + ": no Pixel Spacing (0028,0030)");
                if (std::fabs(g.spacing[0] - g0.spacing[0]) > 1e-6 * g0.spacing[0] ||
                    std::fabs(g.spacing[1] - g0.spacing[1]) > 1e-6 * g0.spacing[1])
                    throw IoError(ISOMEND_IO_ERR_MISMATCH,
                                  name + ": Pixel Spacing " + num(g.spacing[0]) + "\\" + num(g.spacing[1]) +
                                      differs + " " + num(g0.spacing[0]) + "\\" + num(g0.spacing[1]));
            }
            if (!(g.slope != 0.0) || !std::isfinite(g.slope) || !std::isfinite(g.intercept))
                throw IoError(ISOMEND_IO_ERR_CORRUPT, name + ": Rescale Slope " + num(g.slope) + " is not usable");
            DicomFrame f;
            f.path = h.path;
            f.frame = k;
            std::memcpy(f.position, g.position, sizeof f.position);
            f.slope = g.slope;
            f.intercept = g.intercept;
            out.frames.push_back(f);
        }
    }
    if (members.size() == 1 && h0.frames > 1) out.multiframe = true;
    // orientation: two unit vectors at right angles
    const double *row = g0.orientation, *col = g0.orientation + 3;
    double lr = std::sqrt(dot(row, row)), lc = std::sqrt(dot(col, col));
    if (std::fabs(lr - 1) > 1e-3 || std::fabs(lc - 1) > 1e-3 || std::fabs(dot(row, col)) > 1e-3)
        throw IoError(ISOMEND_IO_ERR_CORRUPT, h0.path + ": Image Orientation (Patient) is not two unit vectors "
                                                        "at right angles");
    double r[3], c[3], n[3];
    for (int a = 0; a < 3; a++) {
        r[a] = row[a] / lr;
        c[a] = col[a] / lc;
    }
    n[0] = r[1] * c[2] - r[2] * c[1];
    n[1] = r[2] * c[0] - r[0] * c[2];
    n[2] = r[0] * c[1] - r[1] * c[0];
    double ln = std::sqrt(dot(n, n));
    for (int a = 0; a < 3; a++) n[a] /= ln;
    std::memcpy(out.orientation, g0.orientation, sizeof out.orientation);
    std::memcpy(out.normal, n, sizeof n);
    for (auto &f : out.frames) f.along = dot(f.position, n);
    std::stable_sort(out.frames.begin(), out.frames.end(),
                     [](const DicomFrame &a, const DicomFrame &b) { return a.along < b.along; });
    auto frame_name = [&](const DicomFrame &f) {
        return f.path + (out.multiframe || h0.frames > 1 ? " (frame " + std::to_string(f.frame + 1) + ")" : "");
    };
    auto short_name = [&](const DicomFrame &f) {
        size_t slash = f.path.find_last_of('/');
        return (slash == std::string::npos ? f.path : f.path.substr(slash + 1)) +
               (out.multiframe || h0.frames > 1 ? ", frame " + std::to_string(f.frame + 1) : "");
    };
    const size_t nf = out.frames.size();
    if (nf < 2)
        throw IoError(ISOMEND_IO_ERR_TOO_FEW_SLICES,
                      h0.path + ": a single DICOM image; a volume needs at least two slices (a folder of the "
                                "series' files, a DICOMDIR or a multi-frame file)");
    double sx = o.spacing_given ? 1.0 : g0.spacing[1], sy = o.spacing_given ? 1.0 : g0.spacing[0];
    const double pixel = std::min(sx, sy);
    for (size_t k = 1; k < nf; k++)
        if (out.frames[k].along - out.frames[k - 1].along <= kDuplicateTolerance * pixel)
            throw IoError(ISOMEND_IO_ERR_MISMATCH,
                          frame_name(out.frames[k]) + ": at the same position along the slice normal (" +
                              mm(out.frames[k].along) + ") as " + frame_name(out.frames[k - 1]) +
                              ": a duplicated slice, or several echoes / time points in one series");
    // where the slices are: each frame's origin in the series' own frame
    std::vector<double> origins(3 * nf);
    for (size_t k = 0; k < nf; k++) {
        origins[3 * k] = dot(r, out.frames[k].position);
        origins[3 * k + 1] = dot(c, out.frames[k].position);
        origins[3 * k + 2] = dot(n, out.frames[k].position);
    }
    measure_slices(std::move(origins), kUniformTolerance * pixel, out.geometry);
    if (o.spacing_given) { // the caller's spacing replaces the positions: an evenly spaced grid
        out.geometry.origins.clear();
        out.geometry.uniform = true;
    }
    out.geometry.warning =
        gap_warning(out.geometry,
                    o.spacing_given ? "meshed evenly at the spacing given instead"
                                    : "meshed at the slices' true positions",
                    [&](int64_t k) {
                        return std::to_string(k) + " (" + short_name(out.frames[(size_t)k]) + ")";
                    });
    const DicomFrame &f0 = out.frames[0];
    // spacing, frames
    out.spacing[0] = sx;
    out.spacing[1] = sy;
    out.spacing[2] = (out.frames.back().along - f0.along) / (double)(nf - 1);
    out.spacing_source[0] = out.spacing_source[1] = o.spacing_given ? ISOMEND_IO_SPACING_OPTION : ISOMEND_IO_SPACING_DICOM;
    out.spacing_source[2] = ISOMEND_IO_SPACING_POSITIONS;
    std::memcpy(out.position, f0.position, sizeof out.position);
    // R = [r | c | n]; origin in the series' own frame R^T P0; affine own -> world
    for (int a = 0; a < 3; a++) {
        out.rotation[3 * a + 0] = r[a];
        out.rotation[3 * a + 1] = c[a];
        out.rotation[3 * a + 2] = n[a];
    }
    out.origin[0] = dot(r, f0.position);
    out.origin[1] = dot(c, f0.position);
    out.origin[2] = dot(n, f0.position);
    const double *R = out.rotation;
    out.identity = R[0] == 1 && R[1] == 0 && R[2] == 0 && R[3] == 0 && R[4] == 1 && R[5] == 0 && R[6] == 0 &&
                   R[7] == 0 && R[8] == 1;
    if (o.axes == ISOMEND_IO_AXES_GRID) out.identity = true;
    for (int i = 0; i < 12; i++) out.affine[i] = (i % 5 == 0) ? 1.0 : 0.0;
    if (!out.identity) {
        for (int rr = 0; rr < 3; rr++) {
            for (int cc = 0; cc < 3; cc++) out.affine[4 * rr + cc] = R[3 * rr + cc];
            out.affine[4 * rr + 3] =
                f0.position[rr] - (R[3 * rr] * out.origin[0] + R[3 * rr + 1] * out.origin[1] + R[3 * rr + 2] * out.origin[2]);
        }
    }
    // 5. type
    choose_type(out);
    std::string rt = g0.rescale_type;
    out.hounsfield = out.modality == "CT" && (rt.empty() || rt == "HU");
}

// ---------------------------------------------------------------- decoding

namespace {

struct Decoded {
    // native little-endian pixel data are used where GDCM's reader holds them
    // (no copy); everything else is decoded by gdcm::ImageReader into buffer
    std::unique_ptr<gdcm::Reader> reader;
    std::vector<char> buffer;
    const char *data = nullptr;
    gdcm::PixelFormat::ScalarType scalar = gdcm::PixelFormat::UNKNOWN;
    size_t frame_samples = 0;
    int64_t frames = 0;
};

size_t scalar_size(gdcm::PixelFormat::ScalarType t) {
    switch (t) {
    case gdcm::PixelFormat::UINT8:
    case gdcm::PixelFormat::INT8: return 1;
    case gdcm::PixelFormat::UINT16:
    case gdcm::PixelFormat::INT16: return 2;
    case gdcm::PixelFormat::UINT32:
    case gdcm::PixelFormat::INT32: return 4;
    default: return 0;
    }
}

// DICOM RLE Lossless (PS3.5 Annex G): one fragment per frame, a 64-byte
// header (segment count, 15 offsets), one PackBits segment per byte of the
// sample, most significant byte first.  GDCM 3.0's decoder writes byte by
// byte into a std::ostream (and ImageReader::Read() decodes once more to
// check the stream): 36 ms per 512 x 512 slice; this loop takes under 1 ms.
void rle_decode(const std::string &path, const char *src, size_t len, size_t samples, size_t es, int64_t frame,
                char *out) {
    auto corrupt = [&](const std::string &why) {
        return IoError(ISOMEND_IO_ERR_CORRUPT,
                       path + ": RLE frame " + std::to_string(frame + 1) + ": " + why + " (truncated or corrupt)");
    };
    auto u32 = [&](size_t at) {
        const unsigned char *b = (const unsigned char *)src + at;
        return (uint32_t)b[0] | (uint32_t)b[1] << 8 | (uint32_t)b[2] << 16 | (uint32_t)b[3] << 24;
    };
    if (len < 64) throw corrupt("no RLE header");
    if (u32(0) != es) throw corrupt(std::to_string(u32(0)) + " segments for " + std::to_string(es) + "-byte samples");
    for (size_t seg = 0; seg < es; seg++) {
        size_t at = u32(4 + 4 * seg), end = seg + 1 < es ? u32(8 + 4 * seg) : len;
        if (at < 64 || end > len || at > end) throw corrupt("segment offsets out of the fragment");
        const size_t byte = es - 1 - seg; // segment 0 holds the most significant byte
        size_t n = 0;
        while (n < samples && at < end) {
            int c = (signed char)src[at++];
            if (c >= 0) {
                size_t run = (size_t)c + 1;
                if (at + run > end || n + run > samples) throw corrupt("a literal run past the segment");
                for (size_t k = 0; k < run; k++) out[(n + k) * es + byte] = src[at + k];
                at += run;
                n += run;
            } else if (c != -128) {
                size_t run = (size_t)(1 - c);
                if (at >= end || n + run > samples) throw corrupt("a repeat run past the segment");
                char v = src[at++];
                for (size_t k = 0; k < run; k++) out[(n + k) * es + byte] = v;
                n += run;
            }
        }
        if (n != samples) throw corrupt("segment " + std::to_string(seg + 1) + " decodes to " + std::to_string(n) +
                                        " of " + std::to_string(samples) + " samples");
    }
}

// What gdcm::Reader alone can give: uncompressed little-endian pixel data
// used where the reader holds them (GDCM's Image::GetBuffer() would copy
// them once more: 0.6 s of the 0.9 s GDCM spends on 300 CT slices of
// 512 x 512), or RLE decoded here.  False: another transfer syntax.
bool reader_pixels(const DicomSeries &s, const std::string &path, Decoded &d) {
    std::unique_ptr<gdcm::Reader> r(new gdcm::Reader);
    r->SetFileName(path.c_str());
    if (!r->Read())
        throw IoError(ISOMEND_IO_ERR_CORRUPT, path + ": cannot read the file (GDCM): truncated or corrupt");
    const gdcm::TransferSyntax &ts = r->GetFile().GetHeader().GetDataSetTransferSyntax();
    const bool rle = ts == gdcm::TransferSyntax::RLELossless;
    if (!rle && ts != gdcm::TransferSyntax::ImplicitVRLittleEndian && ts != gdcm::TransferSyntax::ExplicitVRLittleEndian &&
        ts != gdcm::TransferSyntax::DeflatedExplicitVRLittleEndian)
        return false;
    const gdcm::DataSet &ds = r->GetFile().GetDataSet();
    if (!ds.FindDataElement(kPixelData)) throw IoError(ISOMEND_IO_ERR_CORRUPT, path + ": no Pixel Data");
    const gdcm::DataElement &pd = ds.GetDataElement(kPixelData);
    d.frames = 1;
    double v;
    if (number_of(ds, 0x0028, 0x0008, &v) && v >= 1) d.frames = (int64_t)v;
    d.frame_samples = (size_t)s.width * (size_t)s.height;
    const size_t es = (size_t)s.bits_allocated / 8;
    const size_t need = d.frame_samples * (size_t)d.frames * es;
    d.scalar = es == 1 ? (s.pixel_signed ? gdcm::PixelFormat::INT8 : gdcm::PixelFormat::UINT8)
               : es == 2 ? (s.pixel_signed ? gdcm::PixelFormat::INT16 : gdcm::PixelFormat::UINT16)
                         : (s.pixel_signed ? gdcm::PixelFormat::INT32 : gdcm::PixelFormat::UINT32);
    if (rle) {
        const gdcm::SequenceOfFragments *sf = pd.GetSequenceOfFragments();
        if (!sf || (int64_t)sf->GetNumberOfFragments() != d.frames) return false; // let GDCM sort it out
        d.buffer.resize(need);
        for (int64_t k = 0; k < d.frames; k++) {
            const gdcm::ByteValue *bv = sf->GetFragment((size_t)k).GetByteValue();
            if (!bv || !bv->GetPointer())
                throw IoError(ISOMEND_IO_ERR_CORRUPT, path + ": RLE frame " + std::to_string(k + 1) + " is empty");
            rle_decode(path, bv->GetPointer(), bv->GetLength(), d.frame_samples, es, k,
                       d.buffer.data() + (size_t)k * d.frame_samples * es);
        }
        d.data = d.buffer.data();
        return true;
    }
    const gdcm::ByteValue *bv = pd.GetByteValue();
    if (!bv || !bv->GetPointer() || bv->GetLength() < need)
        throw IoError(ISOMEND_IO_ERR_CORRUPT, path + ": pixel data of " + std::to_string(bv ? (uint64_t)bv->GetLength() : 0) +
                                                  " bytes, expected " + std::to_string(need) + " (truncated or corrupt)");
    d.data = bv->GetPointer();
    d.reader = std::move(r);
    return true;
}

void decode_file(const DicomSeries &s, const std::string &path, Decoded &d) {
    quiet_gdcm();
    if (reader_pixels(s, path, d)) return;
    gdcm::ImageReader r;
    r.SetFileName(path.c_str());
    if (!r.Read())
        throw IoError(ISOMEND_IO_ERR_CORRUPT, path + ": cannot read the image (GDCM): truncated or corrupt file");
    const gdcm::Image &img = r.GetImage();
    const unsigned *dims = img.GetDimensions();
    int64_t frames = img.GetNumberOfDimensions() >= 3 ? (int64_t)dims[2] : 1;
    if ((int)dims[0] != s.width || (int)dims[1] != s.height)
        throw IoError(ISOMEND_IO_ERR_MISMATCH, path + ": decoded size " + std::to_string(dims[0]) + "x" +
                                                   std::to_string(dims[1]) + " differs from the header's " +
                                                   std::to_string(s.width) + "x" + std::to_string(s.height));
    const gdcm::PixelFormat &pf = img.GetPixelFormat();
    d.scalar = pf.GetScalarType();
    const size_t es = scalar_size(d.scalar);
    if (!es)
        throw IoError(ISOMEND_IO_ERR_UNSUPPORTED,
                      path + ": pixel format " + std::string(pf.GetScalarTypeAsString()) + " is not supported");
    if (pf.GetSamplesPerPixel() != 1)
        throw IoError(ISOMEND_IO_ERR_UNSUPPORTED, path + ": decodes to " + std::to_string(pf.GetSamplesPerPixel()) +
                                                      " samples per pixel (a colour image)");
    d.frame_samples = (size_t)s.width * (size_t)s.height;
    d.frames = frames;
    const size_t need = d.frame_samples * (size_t)frames * es;
    const unsigned long len = img.GetBufferLength();
    if (len != need)
        throw IoError(ISOMEND_IO_ERR_CORRUPT, path + ": pixel data of " + std::to_string(len) + " bytes, expected " +
                                                  std::to_string(need) + " (truncated or corrupt)");
    d.buffer.resize(need);
    if (!img.GetBuffer(d.buffer.data()))
        throw IoError(ISOMEND_IO_ERR_CORRUPT,
                      path + ": the pixel data do not decode (" +
                          (img.GetTransferSyntax().GetString() ? img.GetTransferSyntax().GetString() : "?") +
                          "): truncated or corrupt");
    d.data = d.buffer.data();
}

// One stored sample -> its delivered value (mask, sign, MONOCHROME1, rescale).
struct Converter {
    uint64_t mask;
    int shift, bits;
    bool is_signed, invert;
    int64_t smin, smax;
    int64_t stored(uint64_t raw) const {
        uint64_t v = (raw >> shift) & mask;
        int64_t x = (int64_t)v;
        if (is_signed && bits < 64 && (v >> (bits - 1)) & 1u) x -= (int64_t)(uint64_t(1) << bits);
        if (invert) x = smin + smax - x;
        return x;
    }
};

template <typename In, typename Out>
void convert(const In *src, size_t n, const Converter &cv, double slope, double intercept, bool integer, Out *dst) {
    using U = typename std::make_unsigned<In>::type;
    if (integer) {
        const int64_t si = (int64_t)slope, ii = (int64_t)intercept;
        for (size_t i = 0; i < n; i++) dst[i] = (Out)(cv.stored((uint64_t)(U)src[i]) * si + ii);
    } else {
        for (size_t i = 0; i < n; i++) dst[i] = (Out)((double)cv.stored((uint64_t)(U)src[i]) * slope + intercept);
    }
}

// Samples of 8 or 16 bits go through a table of every stored bit pattern
// (mask, sign, inversion and rescale folded in): one load per sample instead
// of the arithmetic of Converter::stored(); 32-bit samples are converted one by one.
template <typename In, typename Out>
void convert_typed(const In *src, size_t n, const Converter &cv, double slope, double intercept, bool integer,
                   Out *dst) {
    using U = typename std::make_unsigned<In>::type;
    if (sizeof(In) <= 2) {
        std::vector<Out> lut((size_t)1 << (8 * sizeof(In)));
        for (size_t raw = 0; raw < lut.size(); raw++) {
            int64_t x = cv.stored(raw);
            lut[raw] = integer ? (Out)(x * (int64_t)slope + (int64_t)intercept) : (Out)((double)x * slope + intercept);
        }
        const Out *t = lut.data();
        for (size_t i = 0; i < n; i++) dst[i] = t[(U)src[i]];
        return;
    }
    convert(src, n, cv, slope, intercept, integer, dst);
}

template <typename In>
void convert_to(const In *src, size_t n, const Converter &cv, const DicomSeries &s, const DicomFrame &f, void *dst) {
    bool integer = !s.rescaled || s.integer_rescale;
    switch (s.type) {
    case ISOMEND_U8: convert_typed(src, n, cv, f.slope, f.intercept, integer, (uint8_t *)dst); break;
    case ISOMEND_I8: convert_typed(src, n, cv, f.slope, f.intercept, integer, (int8_t *)dst); break;
    case ISOMEND_U16: convert_typed(src, n, cv, f.slope, f.intercept, integer, (uint16_t *)dst); break;
    case ISOMEND_I16: convert_typed(src, n, cv, f.slope, f.intercept, integer, (int16_t *)dst); break;
    case ISOMEND_I32: convert_typed(src, n, cv, f.slope, f.intercept, integer, (int32_t *)dst); break;
    case ISOMEND_F32: convert_typed(src, n, cv, f.slope, f.intercept, false, (float *)dst); break;
    case ISOMEND_F64: convert_typed(src, n, cv, f.slope, f.intercept, false, (double *)dst); break;
    }
}

void convert_frame(const DicomSeries &s, const Decoded &d, const DicomFrame &f, void *dst) {
    if (f.frame >= d.frames)
        throw IoError(ISOMEND_IO_ERR_CORRUPT, f.path + ": frame " + std::to_string(f.frame + 1) + " missing (" +
                                                   std::to_string(d.frames) + " decoded)");
    Converter cv;
    cv.bits = s.bits_stored;
    cv.shift = s.high_bit + 1 - s.bits_stored;
    cv.mask = s.bits_stored >= 64 ? ~uint64_t(0) : (uint64_t(1) << s.bits_stored) - 1;
    cv.is_signed = s.pixel_signed;
    cv.invert = s.monochrome1;
    cv.smin = s.smin;
    cv.smax = s.smax;
    const size_t n = d.frame_samples;
    const char *p = d.data;
    switch (d.scalar) {
    case gdcm::PixelFormat::UINT8: convert_to((const uint8_t *)p + n * (size_t)f.frame, n, cv, s, f, dst); break;
    case gdcm::PixelFormat::INT8: convert_to((const int8_t *)p + n * (size_t)f.frame, n, cv, s, f, dst); break;
    case gdcm::PixelFormat::UINT16: convert_to((const uint16_t *)(const void *)p + n * (size_t)f.frame, n, cv, s, f, dst); break;
    case gdcm::PixelFormat::INT16: convert_to((const int16_t *)(const void *)p + n * (size_t)f.frame, n, cv, s, f, dst); break;
    case gdcm::PixelFormat::UINT32: convert_to((const uint32_t *)(const void *)p + n * (size_t)f.frame, n, cv, s, f, dst); break;
    case gdcm::PixelFormat::INT32: convert_to((const int32_t *)(const void *)p + n * (size_t)f.frame, n, cv, s, f, dst); break;
    default: throw IoError(ISOMEND_IO_ERR_UNSUPPORTED, f.path + ": unsupported pixel format");
    }
}

} // namespace

void dicom_read_slice(const DicomSeries &s, int64_t k, void *out) {
    const DicomFrame &f = s.frames[(size_t)k];
    Decoded d;
    decode_file(s, f.path, d);
    convert_frame(s, d, f, out);
}

void dicom_read(const DicomSeries &s, void *buffer, int threads, const std::function<bool(double)> &progress) {
    // one task per file: its frames and their slots
    std::map<std::string, std::vector<size_t>> by_file;
    std::vector<std::string> order;
    for (size_t k = 0; k < s.frames.size(); k++) {
        auto it = by_file.find(s.frames[k].path);
        if (it == by_file.end()) {
            order.push_back(s.frames[k].path);
            by_file[s.frames[k].path].push_back(k);
        } else {
            it->second.push_back(k);
        }
    }
    const size_t sb = s.slice_bytes();
    parallel_for(
        (int64_t)order.size(), threads,
        [&](int64_t t) {
            const std::string &path = order[(size_t)t];
            Decoded d;
            decode_file(s, path, d);
            for (size_t k : by_file.at(path)) convert_frame(s, d, s.frames[k], (char *)buffer + k * sb);
        },
        progress, "reading DICOM images");
}

} // namespace isomend_io
