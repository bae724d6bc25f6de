/*
 * isomend_filter_job.h - the host-independent half of the MeshLab filter
 *
 * The filter "Isosurface from Slice Stack (isomend)" is split in two:
 *
 *   isomend_filter_job.{h,cpp}   (this file)  No MeshLab, no Qt.  Knows the
 *        parameter names, defaults and tooltips, the method and sample-type
 *        lists, turns parameter values into isomend_io / isomend calls, maps
 *        progress to 0..100, and produces the log lines and the error text.
 *        All extraction goes through the C APIs (isomend_io.h, isomend.h).
 *        Also the post-processing (clean-up, smoothing, decimation) of the
 *        core's mesh before it becomes the layer, so both adapters have it.
 *   filter_isomend.{h,cpp}       MeshLab 2020.09's MeshFilterInterface: the
 *        RichParameter list, the progress callback, Log(), and copying the
 *        isomend_mesh into a new CMeshO layer.
 *
 * An adapter for MeshLab 2021.05+ (FilterPlugin, see the guide) is a sibling
 * of filter_isomend.cpp that reuses this file unchanged.
 *
 * Thread safety: a job object is used by one thread at a time.
 */
#ifndef ISOMEND_FILTER_JOB_H
#define ISOMEND_FILTER_JOB_H

#include <functional>
#include <string>
#include <vector>

#include "isomend.h"
#include "isomend_io.h"

namespace isomend_filter {

/* The filter's name, exactly as MeshLab shows it and as .mlx scripts call it. */
extern const char *const kFilterName;
/* The HTML description shown at the top of the dialog. */
extern const char *const kFilterInfo;

/* Parameter names (public: scripts use them) */
extern const char *const kParamSource;
extern const char *const kParamIso;
extern const char *const kParamMethod;
extern const char *const kParamSpacing[3]; /* spacingX, spacingY, spacingZ */
extern const char *const kParamChannel;
extern const char *const kParamPad;
extern const char *const kParamFlip;
extern const char *const kParamRawDims;
extern const char *const kParamRawType;
extern const char *const kParamSeries;   /* DICOM: series N or UID ("" = the only one) */
extern const char *const kParamGridAxes; /* DICOM: the series' own axes, not patient space */
/* Post-processing of the extracted mesh (isomend.h, "post-processing"), in
 * the command line's order: clean-up, smoothing, decimation.  0 = off. */
extern const char *const kParamMinComponent; /* drop components of fewer triangles */
extern const char *const kParamSmooth;       /* windowed sinc smoothing iterations */
extern const char *const kParamDecimate;     /* fraction of the triangles to keep  */
/* Label maps (segmentations): "" = an isosurface at iso; "all" or "1,5,7" =
 * one layer a label (isomend_io_labels_extract), named and coloured from
 * labelTable (a colour table file) or a .seg.nrrd's own keys. */
extern const char *const kParamLabels;
extern const char *const kParamLabelTable;

/* One choice of the "method" enum: display name and core method. */
struct MethodChoice {
    std::string display;
    isomend_method method;
};

/*
 * The methods this build of the core implements, in menu order: "Disambiguated
 * MC", "Original MC", "Durst" first (their indices 0, 1, 2 are stable for
 * scripts), then every other available method in isomend_method order, so a
 * method added to the core appears without editing the adapter.
 */
std::vector<MethodChoice> method_choices();

/* The "rawType" enum: isomend_type_name() of every type, index = isomend_type. */
std::vector<std::string> raw_type_choices();

/* Label, tooltip and default of each parameter (for the dialog). */
struct ParamText {
    const char *label;
    const char *tooltip;
};
ParamText param_text(const char *name);

/* Parameter values, as read from the host. */
struct Params {
    std::string source;
    double iso = 0.5;
    int method_index = 0;          /* index into method_choices()            */
    double spacing[3] = {0, 0, 0}; /* 0 = from the files' metadata, else 1   */
    int channel = -1;              /* -1 = the only channel, or luminance    */
    bool pad = true;
    bool flip_normals = false;
    std::string raw_dims;          /* "nx ny nz" (or "nx,ny,nz", "nxXnyXnz"); "" = not raw */
    int raw_type_index = 0;        /* isomend_type                           */
    std::string series;            /* DICOM series: N or UID; "" = the only one */
    bool grid_axes = false;        /* DICOM: keep the series' own axes        */
    int min_component = 0;         /* triangles; 0 = no clean-up              */
    int smooth_iterations = 0;     /* 0 = no smoothing, else 1..10000         */
    double decimate_ratio = 0.0;   /* 0 = no decimation, else (0, 1]          */
    std::string labels;            /* "" = isosurface; "all" or "L1,L2,..."    */
    std::string label_table;       /* "" = the source's own names, or none    */
};

/* One label of a label map's result: its layer's name, its colour and its
 * mesh (owned by the Job). */
struct LabelLayer {
    int64_t value = 0;
    std::string name;
    uint8_t rgb[3] = {0, 0, 0};
    uint64_t voxels = 0;
    const isomend_mesh *mesh = nullptr;
};

/* Parses the labels parameter ("all", or distinct integers separated by
 * commas or spaces): true and *all or the values; false and a message. */
bool parse_labels(const std::string &text, bool *all, std::vector<int64_t> *values,
                  std::string *message);

/* What the post-processing steps did (a step's flag is false when its
 * parameter was 0). */
struct PostReport {
    bool cleaned = false, smoothed = false, decimated = false;
    isomend_clean_report clean{};
    isomend_smooth_report smooth{};
    isomend_decimate_report decimate{};
    double seconds = 0.0;
};
/* The defaults above, also the dialog's defaults. */
Params default_params();

/*
 * Progress sink: percent 0..100 and a short stage text.  Return false to ask
 * for cancellation (MeshLab 2020.09's callback never does).
 */
using ProgressFn = std::function<bool(int percent, const char *stage)>;

/* The result of a run.  Owns the mesh. */
class Job {
public:
    Job() = default;
    ~Job();
    Job(const Job &) = delete;
    Job &operator=(const Job &) = delete;

    /*
     * Validates the parameters, opens the source, reads it, extracts the
     * surface.  Returns true on success (mesh() non-NULL with at least one
     * triangle).  On failure returns false and error() names the parameter or
     * the file and the reason; log_lines() then holds what was learnt before.
     * Never throws.
     */
    bool run(const Params &params, const ProgressFn &progress);

    /* The isosurface's mesh; nullptr in label-map mode (see labels()). */
    const isomend_mesh *mesh() const { return mesh_; }
    /* Label-map mode (the labels parameter set): one entry a label, in label
     * order, each to become a layer; empty otherwise.  The meshes are placed
     * by world_transform() as mesh() is. */
    const std::vector<LabelLayer> &labels() const { return label_layers_; }
    /* The map from the mesh's positions to the world (a DICOM series' patient
     * transform, 3x4 row-major) or nullptr when it is the identity; copy the
     * mesh through it with isomend_mesh_copy_transformed(). */
    const double *world_transform() const { return has_world_ ? world_ : nullptr; }
    /* The extraction's statistics (before any post-processing: the layer's
     * counts are the mesh's, see post_report()). */
    const isomend_stats &stats() const { return stats_; }
    const PostReport &post_report() const { return post_; }
    /* The new layer's name, see layer_name_for() ("head", "ct"). */
    const std::string &layer_name() const { return layer_name_; }
    /* Lines for the host's log, in order (source, volume, slice geometry,
     * options, counts, histogram, times). */
    const std::vector<std::string> &log_lines() const { return log_; }
    /* The importer's geometry warning (isomend_io_geometry.warning: slices
     * not evenly spaced, a long gap), prefixed with the source, or "" when
     * there is none; the adapter logs it at MeshLab's warning level.  Also
     * set when the run fails later (reading, extraction). */
    const std::string &warning() const { return warning_; }
    /* The slices' geometry as the importer reported it (valid after the
     * source was opened: geometry_known()); its `warning` is NULL (the text
     * is warning()'s). */
    const isomend_io_geometry &geometry() const { return geometry_; }
    bool geometry_known() const { return geometry_known_; }
    const std::string &error() const { return error_; }

private:
    bool fail(const std::string &message);
    bool run_unguarded(const Params &params, const ProgressFn &progress);
    bool postprocess(const Params &params);
    bool run_labels(isomend_io_source *src, bool all, const std::vector<int64_t> &values,
                    isomend_method method, const Params &params, void *state);

    isomend_mesh *mesh_ = nullptr;
    isomend_labels *labels_ = nullptr;
    std::vector<LabelLayer> label_layers_;
    double world_[12] = {1, 0, 0, 0, 0, 1, 0, 0, 0, 0, 1, 0};
    bool has_world_ = false;
    isomend_stats stats_{};
    PostReport post_;
    std::string layer_name_;
    std::vector<std::string> log_;
    std::string warning_;
    isomend_io_geometry geometry_{};
    bool geometry_known_ = false;
    std::string error_;
};

/*
 * The layer name for a source path and its isomend_io_kind (exposed for
 * tests): a folder's name, or its parent's for a generic name ("tiff",
 * "slices", ...); for a pattern or glob, the name of the folder holding it;
 * for a file, its name without the extension.
 */
std::string layer_name_for(const std::string &source, int kind);

/* Parses rawDims; returns false (and a message) on a malformed value. */
bool parse_raw_dims(const std::string &text, int64_t dims[3], std::string *message);

} // namespace isomend_filter

#endif /* ISOMEND_FILTER_JOB_H */
