/*
 * isomend_filter_job.cpp - parameters to isomend_io/isomend calls, no MeshLab
 *
 * The run, in order:
 *   1. validate the parameters that need no file (spacing, rawDims, method),
 *      each error naming the parameter;
 *   2. isomend_io_open(): resolve the source (folder, pattern, glob,
 *      multi-page file, NRRD, raw) and check every slice header.  With
 *      channel -1 the source is opened with ISOMEND_IO_CHANNEL_AUTO (a
 *      single-channel image is its own luminance); if the images have several
 *      channels that is refused as unsupported and the source is reopened
 *      with ISOMEND_IO_CHANNEL_LUMA (Rec.709 luma);
 *   3. the spacing of each axis: the parameter if > 0, else what
 *      isomend_io_spacing() found (file metadata or 1);
 *   4. the slices' geometry (isomend_io_geometry_info): a log line, and the
 *      importer's warning for the host (slices not evenly spaced, a long
 *      gap); such a series is meshed at its slices' true positions, unless
 *      spacingZ is set: then it is opened again with the spacing as
 *      isomend_io_options.spacing, an evenly spaced grid (as the command
 *      line's --spacing);
 *   5. isomend_io_load() reads the volume into the handle's buffer and
 *      describes it, vol.slice_origins included;
 *   6. isomend_extract() with the chosen method and flags; a result without a
 *      triangle is an error (no empty layer), reported with the value range;
 *   7. post-processing, each step a call of the core that keeps a closed,
 *      oriented surface closed, in the command line's order (io/cli/
 *      postprocess.c): clean-up (minComponent: isomend_mesh_clean), smoothing
 *      (smoothIterations: isomend_mesh_smooth), decimation (decimateRatio:
 *      isomend_mesh_decimate); a log line per step, as the CLI's summary.
 * Progress: open 0-5 %, read 5-45 %, extract 45-95 %, post-processing 95-96 %;
 * the adapter's copy into the host's mesh is the rest.
 */
#include "isomend_filter_job.h"

#include <algorithm>
#include <cctype>
#include <cerrno>
#include <cstdarg>
#include <chrono>
#include <cinttypes>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <exception>
#include <memory>
#include <new>
#include <sstream>

#include "isomend_io.h"

namespace isomend_filter {

const char *const kFilterName = "Isosurface from Slice Stack (isomend)";
const char *const kFilterInfo =
    "Builds a triangle mesh of the isosurface of a volume given as a stack of 2D images "
    "(a folder, a printf pattern such as <i>slice_%04d.tif</i>, a glob, a multi-page TIFF), "
    "an NRRD file or a raw file, with <b>isomend</b>.<br>"
    "The default method, <b>Disambiguated MC</b> (Roll, Haase &amp; von Kienlin 1995; "
    "thesis 1996), is marching cubes plus a quadrilateral on every ambiguous face shared by an "
    "<i>inverted combination</i> of cubes, exactly where the original marching cubes "
    "(Lorensen &amp; Cline 1987) leaves holes; Durst (1988) puts a quadrilateral on every "
    "ambiguous face and so adds extraneous polygons.<br>"
    "Samples &gt;= iso are inside. With <i>pad</i> the volume is surrounded by one layer of "
    "outside samples, so the surface is closed. Normals are unit gradient normals pointing "
    "to lower values (outwards for bright objects).<br>"
    "The log lists vertices, triangles (from the table, Durst quads, mending quads) and the "
    "number of cubes in each of the 15 elementary cases.<br>"
    "A folder of DICOM files (or a DICOMDIR, or one multi-frame file) is read as a series: the "
    "mesh "
    "is in patient coordinates (LPS, millimetres), CT values in Hounsfield units (bone: iso 300, "
    "skin: iso -500).<br>"
    "A <b>label map</b> (a segmentation: NIfTI, 3D Slicer .seg.nrrd, NRRD, raw): set <i>labels</i> "
    "to "
    "<i>all</i> or to a list such as <i>1,5,7</i>: one closed layer a label, named and coloured "
    "from <i>labelTable</i> or the .seg.nrrd's own segments (iso is not used).";

const char *const kParamSource = "source";
const char *const kParamIso = "iso";
const char *const kParamMethod = "method";
const char *const kParamSpacing[3] = {"spacingX", "spacingY", "spacingZ"};
const char *const kParamChannel = "channel";
const char *const kParamPad = "pad";
const char *const kParamFlip = "flipNormals";
const char *const kParamRawDims = "rawDims";
const char *const kParamRawType = "rawType";
const char *const kParamSeries = "dicomSeries";
const char *const kParamGridAxes = "dicomGridAxes";
const char *const kParamMinComponent = "minComponent";
const char *const kParamSmooth = "smoothIterations";
const char *const kParamDecimate = "decimateRatio";
const char *const kParamLabels = "labels";
const char *const kParamLabelTable = "labelTable";

namespace {

/* Display names of the methods; the first three are fixed by the spec. */
const char *method_display_name(isomend_method m)
{
    switch (m) {
    case ISOMEND_METHOD_DMC: return "Disambiguated MC";
    case ISOMEND_METHOD_MC: return "Original MC";
    case ISOMEND_METHOD_DURST: return "Durst";
    case ISOMEND_METHOD_FACIAL: return "Facial average";
    case ISOMEND_METHOD_GRADIENT: return "Center-pointing gradient";
    case ISOMEND_METHOD_ASYMPTOTIC: return "Asymptotic decider";
    case ISOMEND_METHOD_TETRA: return "Tetrahedra";
    case ISOMEND_METHOD_MC33: return "Marching Cubes 33";
    }
    return nullptr;
}

std::string format(const char *fmt, ...) __attribute__((format(printf, 1, 2)));
std::string format(const char *fmt, ...)
{
    char buf[1024];
    va_list ap;
    va_start(ap, fmt);
    std::vsnprintf(buf, sizeof buf, fmt, ap);
    va_end(ap);
    return buf;
}

/* Shared by the io and core progress callbacks. */
struct ProgressState {
    const ProgressFn *sink;
    int last = -1;
    bool cancelled = false;
    bool report(int percent, const char *stage)
    {
        if (!*sink)
            return true;
        percent = std::max(last, std::max(0, std::min(100, percent))); /* a reopen restarts */
        if (percent == last)
            return true;
        last = percent;
        if (!(*sink)(percent, stage))
            cancelled = true;
        return !cancelled;
    }
};

int io_progress(void *user, int stage, double fraction)
{
    auto *state = static_cast<ProgressState *>(user);
    if (!(fraction >= 0.0))
        fraction = 0.0;
    if (fraction > 1.0)
        fraction = 1.0;
    switch (stage) {
    case ISOMEND_IO_STAGE_OPEN:
        return state->report(static_cast<int>(5.0 * fraction), "isomend: opening slices") ? 0 : 1;
    case ISOMEND_IO_STAGE_READ:
        return state->report(5 + static_cast<int>(40.0 * fraction), "isomend: reading slices")
                   ? 0
                   : 1;
    default:
        return state->cancelled ? 1 : 0;
    }
}

int core_progress(void *user, double fraction)
{
    auto *state = static_cast<ProgressState *>(user);
    if (!(fraction >= 0.0))
        fraction = 0.0;
    if (fraction > 1.0)
        fraction = 1.0;
    return state->report(45 + static_cast<int>(50.0 * fraction), "isomend: extracting") ? 0 : 1;
}

/* The core's options of a run: the method, pad and flip from the parameters,
 * every core, progress reported to `state`. */
isomend_options core_options(const Params &params, isomend_method method, ProgressState *state)
{
    isomend_options opts;
    isomend_options_init(&opts);
    opts.method = method;
    opts.flags = 0;
    if (params.pad)
        opts.flags |= ISOMEND_FLAG_PAD;
    if (params.flip_normals)
        opts.flags |= ISOMEND_FLAG_FLIP;
    opts.threads = 0;
    opts.progress = core_progress;
    opts.progress_user = state;
    return opts;
}

/* Owns an isomend_io_source. */
struct SourceHandle {
    isomend_io_source *src = nullptr;
    ~SourceHandle() { isomend_io_destroy(src); }
    void reset()
    {
        isomend_io_destroy(src);
        src = nullptr;
    }
};

/* One log line on the slices' geometry: evenly spaced at the z spacing in
 * use (the spacingZ parameter's, if set), or where the gaps differ
 * (isomend_io_geometry's fields; the warning is logged apart). */
std::string geometry_line(const isomend_io_geometry &g, double spacing_z)
{
    if (g.uniform)
        return format("slices evenly spaced, gap %g", spacing_z);
    std::string line = format("slices not evenly spaced, meshed at their positions: gaps %g to %g "
                              "(median %g; %" PRId64 " uneven, %" PRId64 " over 1.5x the median)",
                              g.gap_min, g.gap_max, g.gap_median, g.uneven_gaps, g.long_gaps);
    if (g.tilt_degrees > 0.0)
        line += format(", tilt %.3g degrees", g.tilt_degrees);
    if (g.max_offset > 0.0)
        line += format(", largest offset from an even grid %.3g", g.max_offset);
    return line;
}

double seconds_since(std::chrono::steady_clock::time_point t0)
{
    return std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
}

} // namespace

std::vector<MethodChoice> method_choices()
{
    std::vector<MethodChoice> out;
    const isomend_method first[3] = {ISOMEND_METHOD_DMC, ISOMEND_METHOD_MC, ISOMEND_METHOD_DURST};
    for (isomend_method m : first)
        out.push_back({method_display_name(m), m});
    for (int i = 0; i < ISOMEND_METHOD_COUNT; ++i) {
        auto m = static_cast<isomend_method>(i);
        if (m == ISOMEND_METHOD_DMC || m == ISOMEND_METHOD_MC || m == ISOMEND_METHOD_DURST)
            continue;
        if (!isomend_method_available(m))
            continue;
        const char *name = method_display_name(m);
        if (!name)
            name = isomend_method_name(m);
        if (!name)
            continue;
        out.push_back({name, m});
    }
    return out;
}

std::vector<std::string> raw_type_choices()
{
    std::vector<std::string> out;
    for (int i = 0; i < ISOMEND_TYPE_COUNT; ++i)
        out.push_back(isomend_type_name(static_cast<isomend_type>(i)));
    return out;
}

ParamText param_text(const char *name)
{
    const std::string n = name;
    if (n == kParamSource)
        return {"Source",
                "The volume: a folder of slice images (natural order, the folder's most common "
                "image extension), a printf pattern (/data/slice_%04d.tif), a glob "
                "(/data/slice_*.png), a multi-page TIFF, an NRRD file (.nrrd/.nhdr), a NIfTI file "
                "(.nii/.nii.gz/.hdr, placed by its sform/qform in patient LPS mm), or a raw "
                "file (then set rawDims and rawType)."};
    if (n == kParamIso)
        return {"Iso level",
                "The isosurface level, in the samples' own units (no normalisation: 0..255 for "
                "8-bit, 0..65535 for 16-bit; Hounsfield units for CT DICOM: bone 300, skin -500). "
                "Samples >= iso are inside."};
    if (n == kParamMethod)
        return {"Method",
                "Disambiguated MC: marching cubes plus a mending quad only on ambiguous faces "
                "shared by an inverted combination (hole-free, no extraneous polygons). "
                "Original MC: Lorensen & Cline's table only (can leave holes). Durst: a quad on "
                "every ambiguous face (hole-free, with extraneous polygons). Further methods, "
                "when this build has them: Facial average, Center-pointing gradient and Asymptotic decider "
                "(face decisions shared by both cubes), Tetrahedra (five mirrored tetrahedra per "
                "cube), Marching Cubes 33 (also resolves interior ambiguities)."};
    if (n == kParamSpacing[0])
        return {"Spacing X", "World distance between columns. 0 = from the files' metadata "
                             "(TIFF resolution, NRRD header), else 1."};
    if (n == kParamSpacing[1])
        return {"Spacing Y", "World distance between rows. 0 = from the files' metadata "
                             "(TIFF resolution, NRRD header), else 1."};
    if (n == kParamSpacing[2])
        return {"Spacing Z", "World distance between slices. 0 = from the files' metadata "
                             "(ImageJ spacing=, NRRD header; a DICOM series' slice positions, "
                             "also when they are not evenly spaced), else 1. Set: the slices "
                             "are evenly spaced at this distance."};
    if (n == kParamChannel)
        return {"Channel", "Image channel to use (0 = first). -1 = luminance: the only channel "
                           "of a grey image, the Rec.709 luma of an RGB(A) image."};
    if (n == kParamPad)
        return {"Pad (closed surface)",
                "Surround the volume with one layer of outside samples so that the surface is "
                "closed where the object touches the volume's border."};
    if (n == kParamFlip)
        return {"Flip normals", "Point the normals towards higher values (inwards for bright "
                                "objects); the triangle winding is reversed to match."};
    if (n == kParamRawDims)
        return {"Raw dimensions",
                "Only for a raw (headerless) file: the volume's size as \"nx ny nz\" (x "
                "fastest). Leave empty for images and NRRD files."};
    if (n == kParamSeries)
        return {"DICOM series",
                "Only for a DICOM folder holding several series: the series' number as the error "
                "message lists them (1, 2, ...) or its Series Instance UID. Empty: the only series."};
    if (n == kParamGridAxes)
        return {"DICOM grid axes",
                "Keep a DICOM series' own axes (columns, rows, slices) instead of placing the mesh in "
                "patient coordinates (LPS mm, turned by the series' orientation)."};
    if (n == kParamMinComponent)
        return {"Minimum component",
                "Post-processing, first: drop the connected pieces of the mesh with fewer "
                "triangles than this (specks of noise). 0 = keep everything."};
    if (n == kParamSmooth)
        return {"Smoothing iterations",
                "Post-processing, second: windowed sinc smoothing iterations (the filter of VTK and "
                "3D Slicer) that remove the voxel staircase without shrinking (the enclosed volume "
                "is restored); the surface stays closed. 0 = off."};
    if (n == kParamDecimate)
        return {"Decimation ratio",
                "Post-processing, last: the fraction of the triangles to keep (0.2 = a fifth), by "
                "quadric edge collapse that keeps the surface closed and 2-manifold; the log says "
                "whether the target was reached and the largest error. 0 = off."};
    if (n == kParamLabels)
        return {"Label map: labels",
                "Empty: an isosurface at iso. \"all\" (every value but 0) or labels such as "
                "\"1,5,7\": the volume is a label map (a segmentation) and each label becomes its "
                "own layer, named and coloured, closed with pad (methods: Disambiguated MC, "
                "Original MC, Durst; iso and post-processing are not used)."};
    if (n == kParamLabelTable)
        return {"Label map: colour table",
                "Names and colours of the labels: a 3D Slicer colour table (.ctbl/.txt), "
                "FreeSurfer's FreeSurferColorLUT.txt or an ITK-SNAP label description. Empty: a "
                ".seg.nrrd's own segment names and colours, else label_N and a fixed palette."};
    if (n == kParamRawType)
        return {"Raw sample type",
                "Only for a raw file: the sample type (little-endian). Ignored when rawDims is "
                "empty."};
    return {name, ""};
}

Params default_params()
{
    return Params();
}

std::string layer_name_for(const std::string &source, int kind)
{
    /* Folder names that say nothing about the stack: the parent's is used
     * (the Blender add-on names its objects the same way). */
    static const char *const generic[] = {"tif", "tiff", "png", "exr", "jpg", "slices",
                                          "images", "image", "stack", "data"};
    auto split = [](std::string path, std::string *parent) {
        while (path.size() > 1 && path.back() == '/')
            path.pop_back();
        const size_t slash = path.find_last_of('/');
        if (parent)
            *parent = slash == std::string::npos ? std::string() : path.substr(0, slash);
        return slash == std::string::npos ? path : path.substr(slash + 1);
    };
    auto folder_name = [&](const std::string &folder) {
        std::string parent;
        std::string name = split(folder, &parent);
        std::string lower = name;
        for (char &c : lower)
            c = static_cast<char>(std::tolower(static_cast<unsigned char>(c)));
        for (const char *g : generic)
            if (lower == g) {
                const std::string up = split(parent, nullptr);
                if (!up.empty() && up != "/" && up != "." && up != "..")
                    return up;
            }
        return name;
    };
    std::string name;
    if (kind == ISOMEND_IO_KIND_FOLDER) {
        name = folder_name(source);
    } else if (kind == ISOMEND_IO_KIND_PATTERN || kind == ISOMEND_IO_KIND_GLOB) {
        std::string parent;
        name = split(source, &parent);
        if (!parent.empty())
            name = folder_name(parent);
    } else {
        name = split(source, nullptr);
        const size_t dot = name.find_last_of('.');
        if (dot != std::string::npos && dot > 0)
            name.erase(dot);
    }
    if (name.empty() || name == "/" || name == "." || name == "..")
        return "isosurface";
    return name;
}

bool parse_raw_dims(const std::string &text, int64_t dims[3], std::string *message)
{
    std::string t = text;
    for (char &c : t)
        if (c == ',' || c == 'x' || c == 'X' || c == ';' || c == '\t')
            c = ' ';
    int n = 0;
    const char *p = t.c_str();
    while (*p) {
        while (*p == ' ')
            ++p;
        if (!*p)
            break;
        if (n == 3) {
            *message = "rawDims: more than three numbers in \"" + text + "\"";
            return false;
        }
        char *end = nullptr;
        errno = 0;
        long long v = std::strtoll(p, &end, 10);
        if (end == p || (*end && *end != ' ') || errno != 0 || v <= 0) {
            *message = "rawDims: \"" + text + "\" is not three positive integers (\"nx ny nz\")";
            return false;
        }
        dims[n++] = v;
        p = end;
    }
    if (n != 3) {
        *message = "rawDims: \"" + text + "\" is not three positive integers (\"nx ny nz\")";
        return false;
    }
    return true;
}

bool parse_labels(const std::string &text, bool *all, std::vector<int64_t> *values,
                  std::string *message)
{
    *all = false;
    values->clear();
    std::string t = text;
    std::replace(t.begin(), t.end(), ',', ' ');
    std::istringstream in(t);
    std::string item;
    while (in >> item) {
        if (item == "all" && !*all && values->empty()) {
            *all = true;
            continue;
        }
        char *end = nullptr;
        errno = 0;
        const long long v = std::strtoll(item.c_str(), &end, 10);
        if (*all || errno || !end || *end) {
            *message = format("%s: \"%s\" is not \"all\" or integer labels (1,5,7)", kParamLabels,
                              text.c_str());
            return false;
        }
        if (std::find(values->begin(), values->end(), v) != values->end()) {
            *message = format("%s: label %lld is listed twice", kParamLabels, v);
            return false;
        }
        values->push_back(v);
    }
    if (!*all && values->empty()) {
        *message = format("%s: no label given (\"all\", or labels such as 1,5,7)", kParamLabels);
        return false;
    }
    return true;
}

Job::~Job()
{
    isomend_mesh_destroy(mesh_);
    isomend_labels_destroy(labels_);
}

bool Job::fail(const std::string &message)
{
    error_ = message;
    isomend_mesh_destroy(mesh_);
    mesh_ = nullptr;
    label_layers_.clear();
    isomend_labels_destroy(labels_);
    labels_ = nullptr;
    return false;
}

bool Job::run(const Params &params, const ProgressFn &progress)
{
    isomend_mesh_destroy(mesh_);
    mesh_ = nullptr;
    label_layers_.clear();
    isomend_labels_destroy(labels_);
    labels_ = nullptr;
    stats_ = isomend_stats{};
    post_ = PostReport{};
    log_.clear();
    warning_.clear();
    geometry_ = isomend_io_geometry{};
    geometry_known_ = false;
    error_.clear();
    layer_name_.clear();
    try {
        return run_unguarded(params, progress);
    } catch (const std::bad_alloc &) {
        return fail("out of memory");
    } catch (const std::exception &e) {
        return fail(std::string("unexpected error: ") + e.what());
    } catch (...) {
        return fail("unexpected error");
    }
}

bool Job::run_unguarded(const Params &params, const ProgressFn &progress)
{
    const auto t_start = std::chrono::steady_clock::now();

    /* 1. parameters that need no file */
    std::string source = params.source;
    while (!source.empty() && std::isspace(static_cast<unsigned char>(source.back())))
        source.pop_back();
    while (!source.empty() && std::isspace(static_cast<unsigned char>(source.front())))
        source.erase(source.begin());
    if (source.empty())
        return fail("source: no folder, pattern or file given");
    if (!std::isfinite(params.iso))
        return fail("iso: the level must be a finite number");
    const std::vector<MethodChoice> methods = method_choices();
    if (params.method_index < 0 || params.method_index >= static_cast<int>(methods.size()))
        return fail(format("method: index %d is not one of the %zu methods of this build",
                           params.method_index, methods.size()));
    const MethodChoice method = methods[static_cast<size_t>(params.method_index)];
    for (int a = 0; a < 3; ++a)
        if (!std::isfinite(params.spacing[a]) || params.spacing[a] < 0.0)
            return fail(format("%s: %g is not a spacing (0 = from the files, or > 0)",
                               kParamSpacing[a], params.spacing[a]));
    if (params.channel < -1)
        return fail(format("channel: %d is not a channel (-1 = luminance, 0, 1, ...)",
                           params.channel));
    if (params.min_component < 0)
        return fail(format("%s: %d is not a triangle count (0 = off)", kParamMinComponent,
                           params.min_component));
    if (params.smooth_iterations < 0 || params.smooth_iterations > 10000)
        return fail(
            format("%s: %d is not 0 (off) to 10000", kParamSmooth, params.smooth_iterations));
    if (!std::isfinite(params.decimate_ratio) || params.decimate_ratio < 0.0 ||
        params.decimate_ratio > 1.0)
        return fail(format("%s: %g is not a fraction of the triangles to keep (0 = off, or up "
                           "to 1)",
                           kParamDecimate, params.decimate_ratio));

    std::string labels_text = params.labels;
    labels_text.erase(std::remove_if(labels_text.begin(), labels_text.end(),
                                     [](unsigned char c) { return std::isspace(c) != 0; }),
                      labels_text.end());
    const bool label_mode = !labels_text.empty();
    bool all_labels = false;
    std::vector<int64_t> label_values;
    if (label_mode) {
        std::string message;
        if (!parse_labels(params.labels, &all_labels, &label_values, &message))
            return fail(message);
        if (method.method != ISOMEND_METHOD_DMC && method.method != ISOMEND_METHOD_MC &&
            method.method != ISOMEND_METHOD_DURST)
            return fail(format("%s: a label map takes Disambiguated MC, Original MC or Durst, "
                               "not %s",
                               kParamMethod, method.display.c_str()));
        if (params.min_component > 0 || params.smooth_iterations > 0 || params.decimate_ratio > 0.0)
            return fail(format("%s: the post-processing (%s, %s, %s) does not apply to a label "
                               "map (smoothing one label alone would move the boundary it shares)",
                               kParamLabels, kParamMinComponent, kParamSmooth, kParamDecimate));
    } else if (!params.label_table.empty()) {
        return fail(format("%s: only with %s (a label map)", kParamLabelTable, kParamLabels));
    }

    isomend_io_options io_opts;
    isomend_io_options_init(&io_opts);
    std::string raw_dims = params.raw_dims;
    raw_dims.erase(std::remove_if(raw_dims.begin(), raw_dims.end(),
                                  [](unsigned char c) { return std::isspace(c) != 0; }),
                   raw_dims.end());
    const bool raw = !raw_dims.empty();
    if (raw) {
        std::string message;
        if (!parse_raw_dims(params.raw_dims, io_opts.raw_dims, &message))
            return fail(message);
        if (params.raw_type_index < 0 || params.raw_type_index >= ISOMEND_TYPE_COUNT)
            return fail(format("rawType: index %d is not a sample type", params.raw_type_index));
        io_opts.raw_type = static_cast<isomend_type>(params.raw_type_index);
    }

    ProgressState state{&progress};
    io_opts.progress = io_progress;
    io_opts.progress_user = &state;
    io_opts.channel = params.channel >= 0 ? params.channel : ISOMEND_IO_CHANNEL_AUTO;
    /* 2. open */
    const char *path = source.c_str();
    SourceHandle handle;
    if (isomend_io_create(&handle.src) != ISOMEND_IO_OK)
        return fail("out of memory");
    std::string series = params.series;
    while (!series.empty() && std::isspace(static_cast<unsigned char>(series.back())))
        series.pop_back();
    while (!series.empty() && std::isspace(static_cast<unsigned char>(series.front())))
        series.erase(series.begin());
    auto dicom_choices = [&](isomend_io_source *src) {
        if (!series.empty())
            isomend_io_set_series(src, series.c_str());
        if (params.grid_axes)
            isomend_io_set_axes(src, ISOMEND_IO_AXES_GRID);
    };
    dicom_choices(handle.src);
    isomend_io_status st = isomend_io_open(handle.src, &path, 1, &io_opts);
    bool luma = false;
    if (st == ISOMEND_IO_ERR_UNSUPPORTED && params.channel == -1 && !raw) {
        /* Several channels: retry with their luminance; keep the first message
         * if that fails too (the reason may be something else). */
        const std::string first_message = isomend_io_message(handle.src);
        SourceHandle retry;
        if (isomend_io_create(&retry.src) != ISOMEND_IO_OK)
            return fail("out of memory");
        io_opts.channel = ISOMEND_IO_CHANNEL_LUMA;
        dicom_choices(retry.src);
        if (isomend_io_open(retry.src, &path, 1, &io_opts) == ISOMEND_IO_OK) {
            std::swap(handle.src, retry.src);
            st = ISOMEND_IO_OK;
            luma = true;
        } else {
            /* e.g. grey + alpha: neither one channel nor R, G, B */
            return fail(std::string("source: ") + first_message +
                        " [in MeshLab: set the channel parameter to 0, 1, ...]");
        }
    }
    if (state.cancelled)
        return fail("cancelled");
    if (st != ISOMEND_IO_OK) {
        const char *m = isomend_io_message(handle.src);
        return fail(std::string("source: ") +
                    (m && *m ? m : isomend_io_status_string(st)));
    }

    int64_t dims[3] = {0, 0, 0};
    isomend_type type = ISOMEND_U8;
    double spacing[3] = {1, 1, 1};
    int spacing_src[3] = {0, 0, 0};
    if (isomend_io_dims(handle.src, dims) != ISOMEND_IO_OK ||
        isomend_io_type(handle.src, &type) != ISOMEND_IO_OK ||
        isomend_io_spacing(handle.src, spacing, spacing_src) != ISOMEND_IO_OK)
        return fail(std::string("source: ") + isomend_io_message(handle.src));

    /* 3. spacing: the parameter where set, else the source's */
    std::string spacing_from[3];
    for (int a = 0; a < 3; ++a) {
        if (params.spacing[a] > 0.0) {
            spacing[a] = params.spacing[a];
            spacing_from[a] = "parameter";
        } else {
            const char *n = isomend_io_spacing_source_name(spacing_src[a]);
            spacing_from[a] = n ? n : "?";
        }
    }

    layer_name_ = layer_name_for(source, isomend_io_source_kind(handle.src));
    const char *kind = isomend_io_kind_name(isomend_io_source_kind(handle.src));
    log_.push_back(format("isomend %s: %s (%s, %s), %" PRId64 " x %" PRId64 " x %" PRId64
                          " %s%s",
                          isomend_version(), source.c_str(), kind ? kind : "?",
                          isomend_io_format(handle.src), dims[0], dims[1], dims[2],
                          isomend_type_name(type), luma ? ", luminance of the channels" : ""));
    log_.push_back(format("spacing %g %g %g (from %s, %s, %s)", spacing[0], spacing[1],
                          spacing[2], spacing_from[0].c_str(), spacing_from[1].c_str(),
                          spacing_from[2].c_str()));
    isomend_io_dicom dicom;
    std::memset(&dicom, 0, sizeof dicom);
    dicom.size = sizeof dicom;
    if (isomend_io_dicom_info(handle.src, &dicom) == ISOMEND_IO_OK) {
        log_.push_back(format("DICOM %s series \"%s\" (%lld files; ignored: %lld without pixel data, "
                              "%lld not DICOM, %lld of other series)%s, %s axes",
                              dicom.modality, dicom.description, static_cast<long long>(dicom.files),
                              static_cast<long long>(dicom.non_image),
                              static_cast<long long>(dicom.non_dicom),
                              static_cast<long long>(dicom.other_series),
                              dicom.hounsfield ? ", values in HU (bone 300, skin -500)" : "",
                              dicom.axes == ISOMEND_IO_AXES_GRID ? "grid" : "patient (LPS mm)"));
    }
    if (params.grid_axes || !series.empty()) {
        if (isomend_io_source_kind(handle.src) != ISOMEND_IO_KIND_DICOM)
            return fail(std::string(params.grid_axes ? kParamGridAxes : kParamSeries) +
                        ": applies to DICOM series only; the source is " + (kind ? kind : "?"));
    }
    int identity = 1;
    has_world_ = isomend_io_world_transform(handle.src, world_, &identity) == ISOMEND_IO_OK && !identity;

    /* 4. the slices' geometry: a series whose slices are not evenly spaced (a
     * DICOM series with rounded positions, a spacing change, a gantry tilt,
     * a missing slice) is meshed at their true positions: isomend_io_load()
     * puts them in vol.slice_origins */
    std::string geometry_warning;
    auto read_geometry = [&]() {
        geometry_ = isomend_io_geometry{};
        geometry_.size = sizeof geometry_;
        geometry_known_ = isomend_io_geometry_info(handle.src, &geometry_) == ISOMEND_IO_OK;
        geometry_warning = geometry_known_ && geometry_.warning ? geometry_.warning : "";
        geometry_.warning = nullptr; /* the handle's, gone after the run: see warning() */
    };
    read_geometry();
    if (geometry_known_ && !geometry_.uniform && params.spacing[2] > 0.0) {
        /* unless spacingZ is set: then, as the command line's --spacing, the
         * series is an evenly spaced grid of that spacing.  The importer does
         * that with options.spacing (all three axes: the values above), and
         * its warning says so; open again with it. */
        SourceHandle again;
        if (isomend_io_create(&again.src) != ISOMEND_IO_OK)
            return fail("out of memory");
        dicom_choices(again.src);
        for (int a = 0; a < 3; ++a)
            io_opts.spacing[a] = spacing[a];
        st = isomend_io_open(again.src, &path, 1, &io_opts);
        if (state.cancelled)
            return fail("cancelled");
        if (st != ISOMEND_IO_OK)
            return fail(std::string("source: ") + isomend_io_message(again.src));
        std::swap(handle.src, again.src);
        identity = 1;
        has_world_ =
            isomend_io_world_transform(handle.src, world_, &identity) == ISOMEND_IO_OK && !identity;
        read_geometry();
    }
    if (geometry_known_)
        log_.push_back(geometry_line(geometry_, spacing[2]));
    if (!geometry_warning.empty())
        warning_ = source + ": " + geometry_warning;

    if (label_mode) {
        if (!run_labels(handle.src, all_labels, label_values, method.method, params, &state))
            return false;
        log_.push_back(format("time: total %.3f s", seconds_since(t_start)));
        return true;
    }

    /* 5. read (isomend_io_load() fills every field, slice_origins included) */
    isomend_volume vol{};
    double read_seconds = 0.0;
    st = isomend_io_load(handle.src, &vol, &read_seconds);
    if (state.cancelled)
        return fail("cancelled");
    if (st != ISOMEND_IO_OK)
        return fail(std::string("source: ") + isomend_io_message(handle.src));
    for (int a = 0; a < 3; ++a)
        vol.spacing[a] = spacing[a];

    /* 6. extract */
    isomend_options opts = core_options(params, method.method, &state);
    opts.iso = params.iso;
    log_.push_back(format("method %s (%s), iso %g%s%s", method.display.c_str(),
                          isomend_method_name(method.method), params.iso,
                          params.pad ? ", padded" : "",
                          params.flip_normals ? ", normals flipped" : ""));
    const auto t_extract = std::chrono::steady_clock::now();
    isomend_mesh *mesh = nullptr;
    const isomend_status cst = isomend_extract(&vol, &opts, &mesh, &stats_);
    const double extract_seconds = seconds_since(t_extract);
    if (cst != ISOMEND_OK) {
        isomend_mesh_destroy(mesh);
        if (cst == ISOMEND_ERR_CANCELLED)
            return fail("cancelled");
        return fail(std::string("extraction failed: ") + isomend_status_string(cst));
    }
    mesh_ = mesh;

    if (isomend_mesh_triangle_count(mesh_) == 0) {
        isomend_io_summary summary;
        if (isomend_io_analyse(handle.src, &summary) == ISOMEND_IO_OK)
            return fail(format("iso: no surface at level %g: the samples range from %g to %g "
                               "(suggested level %g); nothing was created",
                               params.iso, summary.min, summary.max, summary.suggested_iso));
        return fail(format("iso: no surface at level %g; nothing was created", params.iso));
    }

    log_.push_back(format("vertices %" PRIu64 ", triangles %" PRIu64 " (table %" PRIu64
                          ", Durst %" PRIu64 ", mending %" PRIu64 ")",
                          stats_.vertices, stats_.triangles,
                          stats_.triangles_by_origin[ISOMEND_ORIGIN_TABLE],
                          stats_.triangles_by_origin[ISOMEND_ORIGIN_DURST],
                          stats_.triangles_by_origin[ISOMEND_ORIGIN_MEND]));
    log_.push_back(format("ambiguous faces %" PRIu64 ", inverted combinations %" PRIu64
                          ", NaN samples %" PRIu64,
                          stats_.ambiguous_faces, stats_.inverted_combinations,
                          stats_.nan_samples));
    std::string histogram = format("cases (cubes per elementary case 0..14 of %" PRIu64 "):",
                                   stats_.cubes);
    for (int c = 0; c < 15; ++c)
        histogram += format(" %d:%" PRIu64, c, stats_.case_histogram[c]);
    log_.push_back(histogram);

    /* 7. post-processing */
    if (params.min_component > 0 || params.smooth_iterations > 0 || params.decimate_ratio > 0.0) {
        state.report(95, "isomend: post-processing");
        const auto t_post = std::chrono::steady_clock::now();
        if (!postprocess(params))
            return false;
        post_.seconds = seconds_since(t_post);
        state.report(96, "isomend: post-processing");
        log_.push_back(format("time: read %.3f s, extract %.3f s, post-processing %.3f s, "
                              "total %.3f s",
                              read_seconds, extract_seconds, post_.seconds,
                              seconds_since(t_start)));
        return true;
    }
    log_.push_back(format("time: read %.3f s, extract %.3f s, total %.3f s", read_seconds,
                          extract_seconds, seconds_since(t_start)));
    return true;
}

bool Job::run_labels(isomend_io_source *src, bool all, const std::vector<int64_t> &values,
                     isomend_method method, const Params &params, void *state_ptr)
{
    auto &state = *static_cast<ProgressState *>(state_ptr);
    /* names first: a bad table is refused before the volume is read */
    isomend_io_label_names *names = nullptr;
    std::string table = params.label_table;
    while (!table.empty() && std::isspace(static_cast<unsigned char>(table.back())))
        table.pop_back();
    while (!table.empty() && std::isspace(static_cast<unsigned char>(table.front())))
        table.erase(table.begin());
    if (isomend_io_label_names_read(src, table.empty() ? nullptr : table.c_str(), &names) !=
        ISOMEND_IO_OK)
        return fail(std::string(table.empty() ? kParamSource : kParamLabelTable) + ": " +
                    isomend_io_message(src));
    std::unique_ptr<isomend_io_label_names, void (*)(isomend_io_label_names *)> keep(
        names, isomend_io_label_names_destroy);

    const isomend_options opts = core_options(params, method, &state);
    log_.push_back(format("label map: %s, method %s%s%s",
                          all ? "every label but 0" : params.labels.c_str(),
                          isomend_method_name(method), params.pad ? ", padded" : "",
                          params.flip_normals ? ", normals flipped" : ""));
    const auto t0 = std::chrono::steady_clock::now();
    const isomend_io_status st = isomend_io_labels_extract(
        src, all ? nullptr : values.data(), all ? 0 : values.size(), &opts, &labels_);
    if (state.cancelled || st == ISOMEND_IO_ERR_CANCELLED)
        return fail("cancelled");
    if (st != ISOMEND_IO_OK)
        return fail(
            std::string(st == ISOMEND_IO_ERR_INVALID_ARGUMENT ? kParamLabels : kParamSource) +
            ": " + isomend_io_message(src));
    const double seconds = seconds_since(t0);
    const char *from = isomend_io_label_names_from(names);
    for (size_t q = 0; q < isomend_labels_count(labels_); ++q) {
        LabelLayer l;
        l.value = isomend_labels_value(labels_, q);
        l.voxels = isomend_labels_voxels(labels_, q);
        l.mesh = isomend_labels_mesh(labels_, q);
        char name[256];
        isomend_io_label_name(names, l.value, name, sizeof name, l.rgb);
        l.name = name;
        log_.push_back(format("label %lld \"%s\": %" PRIu64 " voxels, %zu vertices, %zu triangles, "
                              "colour %u %u %u",
                              static_cast<long long>(l.value), name, l.voxels,
                              isomend_mesh_vertex_count(l.mesh),
                              isomend_mesh_triangle_count(l.mesh), l.rgb[0], l.rgb[1], l.rgb[2]));
        label_layers_.push_back(l);
    }
    log_.push_back(format("%zu label%s (names from %s), extracted in %.3f s", label_layers_.size(),
                          label_layers_.size() == 1 ? "" : "s", *from ? from : "none: label_N",
                          seconds));
    return true;
}

bool Job::postprocess(const Params &params)
{
    /* mesh_ is replaced by each step's result; the log lines say what the
     * command line's summary says (io/cli/postprocess.c) */
    auto replace = [this](isomend_mesh *out) {
        isomend_mesh_destroy(mesh_);
        mesh_ = out;
    };
    if (params.min_component > 0) {
        isomend_mesh *out = nullptr;
        const isomend_status st = isomend_mesh_clean(
            mesh_, static_cast<uint64_t>(params.min_component), 0, &out, &post_.clean);
        if (st != ISOMEND_OK) {
            isomend_mesh_destroy(out);
            return fail(std::string("minComponent: clean-up failed: ") + isomend_status_string(st));
        }
        replace(out);
        post_.cleaned = true;
        const isomend_clean_report &c = post_.clean;
        log_.push_back(format("clean-up (components of fewer than %d triangles dropped): %" PRIu64
                              " of %" PRIu64 " components kept, %" PRIu64 " triangles and %" PRIu64
                              " vertices removed",
                              params.min_component, c.components_after, c.components_before,
                              c.triangles_removed, c.vertices_removed));
        if (isomend_mesh_triangle_count(mesh_) == 0)
            return fail(format("minComponent: all %" PRIu64 " components have fewer than %d "
                               "triangles; nothing was created",
                               c.components_before, params.min_component));
    }
    if (params.smooth_iterations > 0) {
        isomend_mesh *out = nullptr;
        const isomend_status st =
            isomend_mesh_smooth(mesh_, params.smooth_iterations, &out, &post_.smooth);
        if (st != ISOMEND_OK) {
            isomend_mesh_destroy(out);
            return fail(std::string("smoothIterations: smoothing failed: ") +
                        isomend_status_string(st));
        }
        replace(out);
        post_.smoothed = true;
        const isomend_smooth_report &r = post_.smooth;
        const double v0 = r.volume_before, v1 = r.volume_after;
        log_.push_back(format("smoothing (%d iterations): %" PRIu64
                              " vertices moved, at most %.4g; volume %.6g -> %.6g (%+.3f %%)",
                              params.smooth_iterations, r.moved_vertices, r.max_displacement, v0,
                              v1, v0 != 0 ? 100.0 * (v1 - v0) / v0 : 0.0));
    }
    if (params.decimate_ratio > 0.0) {
        isomend_decimate_options d;
        isomend_decimate_options_init(&d);
        d.ratio = params.decimate_ratio;
        isomend_mesh *out = nullptr;
        const isomend_status st = isomend_mesh_decimate(mesh_, &d, &out, &post_.decimate);
        if (st != ISOMEND_OK) {
            isomend_mesh_destroy(out);
            return fail(std::string("decimateRatio: decimation failed: ") +
                        isomend_status_string(st));
        }
        replace(out);
        post_.decimated = true;
        const isomend_decimate_report &r = post_.decimate;
        log_.push_back(format("decimation (ratio %g): %" PRIu64 " -> %" PRIu64
                              " triangles, %" PRIu64 " -> %" PRIu64 " vertices (target %" PRIu64
                              ", %s), largest error %.4g, mean %.4g, %" PRIu64 " locked vertices",
                              params.decimate_ratio, r.triangles_before, r.triangles_after,
                              r.vertices_before, r.vertices_after, r.target_triangles,
                              r.reached ? "reached"
                                        : "not reached: further collapses would break the "
                                          "surface",
                              r.max_error, r.mean_error, r.locked_vertices));
    }
    return true;
}

} // namespace isomend_filter
