/*
 * test_job.cpp - the MeshLab filter's host-independent half, without MeshLab
 *
 * Checks what the adapter relies on: the method menu order (scripts call
 * methods by index), the rawType list, rawDims parsing, layer names, and that
 * a run on a raw volume gives exactly the core's mesh (positions, normals,
 * triangles, statistics) with the spacing/pad/flip parameters applied, that
 * progress is monotonic, and that every bad parameter fails with a message
 * naming it and leaves no mesh.  Label maps (the labels parameter): a
 * layer a label, each exactly the core's mesh of its indicator, named and
 * coloured from a .seg.nrrd's keys, a colour table or the palette, and every
 * bad label parameter or sample refused with its message.
 */
#include <algorithm>
#include <cmath>
#include <cstdint>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <string>
#include <unistd.h>
#include <vector>

#include "isomend.h"
#include "isomend_filter_job.h"
#include "isomend_io.h"
#include "testutil.h"

namespace job = isomend_filter;

namespace {

bool contains(const std::string &s, const char *part)
{
    return s.find(part) != std::string::npos;
}

/* A u16 volume: two overlapping blobs plus a saddle-rich ripple, so that
 * the surface has ambiguous faces and DMC mends some of them. */
std::vector<uint16_t> make_volume(int nx, int ny, int nz)
{
    std::vector<uint16_t> v(static_cast<size_t>(nx) * ny * nz);
    for (int z = 0; z < nz; ++z)
        for (int y = 0; y < ny; ++y)
            for (int x = 0; x < nx; ++x) {
                const double a = std::hypot(std::hypot(x - 7.3, y - 8.1), z - 6.2);
                const double b = std::hypot(std::hypot(x - 12.7, y - 9.4), z - 9.9);
                double f = 1000.0 * (std::exp(-a * a / 20.0) + std::exp(-b * b / 14.0));
                f += 300.0 * std::sin(1.9 * x) * std::sin(2.3 * y) * std::sin(1.7 * z);
                f = std::max(0.0, std::min(65535.0, f + 400.0));
                v[(static_cast<size_t>(z) * ny + y) * nx + x] = static_cast<uint16_t>(f);
            }
    return v;
}

struct TempDir {
    std::string path;
    TempDir()
    {
        char tmpl[] = "/tmp/isomend_meshlab_job_XXXXXX";
        const char *p = mkdtemp(tmpl);
        path = p ? p : "";
    }
    ~TempDir()
    {
        if (!path.empty()) {
            std::string cmd = "rm -rf '" + path + "'";
            if (std::system(cmd.c_str()) != 0)
                std::fprintf(stderr, "could not remove %s\n", path.c_str());
        }
    }
};

template <typename T> isomend_type type_of();
template <> isomend_type type_of<uint16_t>()
{
    return ISOMEND_U16;
}
template <> isomend_type type_of<uint8_t>()
{
    return ISOMEND_U8;
}

/* The core's own result, for comparison. */
template <typename T>
isomend_mesh *direct(const std::vector<T> &v, int nx, int ny, int nz, double iso,
                     isomend_method method, unsigned flags, const double spacing[3],
                     isomend_stats *stats)
{
    isomend_volume vol;
    isomend_volume_init(&vol, v.data(), type_of<T>(), nx, ny, nz);
    for (int a = 0; a < 3; ++a)
        vol.spacing[a] = spacing[a];
    isomend_options opts;
    isomend_options_init(&opts);
    opts.iso = iso;
    opts.method = method;
    opts.flags = flags;
    isomend_mesh *mesh = nullptr;
    CHECK_EQ_INT(isomend_extract(&vol, &opts, &mesh, stats), ISOMEND_OK);
    return mesh;
}

void check_same_mesh(const isomend_mesh *a, const isomend_mesh *b)
{
    CHECK(a && b);
    if (!a || !b)
        return;
    const size_t nv = isomend_mesh_vertex_count(a), nt = isomend_mesh_triangle_count(a);
    CHECK_EQ_INT(isomend_mesh_vertex_count(b), nv);
    CHECK_EQ_INT(isomend_mesh_triangle_count(b), nt);
    if (isomend_mesh_vertex_count(b) != nv || isomend_mesh_triangle_count(b) != nt)
        return;
    CHECK(std::memcmp(isomend_mesh_positions(a), isomend_mesh_positions(b),
                      nv * 3 * sizeof(float)) == 0);
    CHECK(std::memcmp(isomend_mesh_normals(a), isomend_mesh_normals(b),
                      nv * 3 * sizeof(float)) == 0);
    CHECK(std::memcmp(isomend_mesh_triangles(a), isomend_mesh_triangles(b),
                      nt * 3 * sizeof(uint32_t)) == 0);
}

void test_lists()
{
    const auto choices = job::method_choices();
    CHECK(choices.size() >= 3);
    if (choices.size() < 3)
        return;
    CHECK(choices[0].display == "Disambiguated MC" && choices[0].method == ISOMEND_METHOD_DMC);
    CHECK(choices[1].display == "Original MC" && choices[1].method == ISOMEND_METHOD_MC);
    CHECK(choices[2].display == "Durst" && choices[2].method == ISOMEND_METHOD_DURST);
    int available = 0;
    for (int m = 0; m < ISOMEND_METHOD_COUNT; ++m)
        available += isomend_method_available(static_cast<isomend_method>(m)) ? 1 : 0;
    CHECK_EQ_INT(choices.size(), available);
    for (size_t i = 0; i < choices.size(); ++i) {
        CHECK(isomend_method_available(choices[i].method));
        CHECK(!choices[i].display.empty());
        for (size_t j = 0; j < i; ++j)
            CHECK(choices[j].method != choices[i].method);
        /* after the first three, core order */
        if (i > 3)
            CHECK(choices[i - 1].method < choices[i].method);
    }

    const auto types = job::raw_type_choices();
    CHECK_EQ_INT(types.size(), ISOMEND_TYPE_COUNT);
    for (int t = 0; t < ISOMEND_TYPE_COUNT && t < static_cast<int>(types.size()); ++t)
        CHECK(types[static_cast<size_t>(t)] == isomend_type_name(static_cast<isomend_type>(t)));

    /* every parameter has a label and a tooltip */
    const char *names[] = {
        job::kParamSource,     job::kParamIso,          job::kParamMethod,  job::kParamSpacing[0],
        job::kParamSpacing[1], job::kParamSpacing[2],   job::kParamChannel, job::kParamPad,
        job::kParamFlip,       job::kParamRawDims,      job::kParamRawType, job::kParamSeries,
        job::kParamGridAxes,   job::kParamMinComponent, job::kParamSmooth,  job::kParamDecimate};
    for (const char *n : names) {
        const job::ParamText t = job::param_text(n);
        CHECK(t.label && *t.label);
        CHECK(t.tooltip && std::strlen(t.tooltip) > 20);
    }
    CHECK(std::string(job::kFilterName) == "Isosurface from Slice Stack (isomend)");
}

void test_parsing()
{
    CHECK(job::layer_name_for("/data/scan/head/", ISOMEND_IO_KIND_FOLDER) == "head");
    CHECK(job::layer_name_for("/data/head/TIFF/", ISOMEND_IO_KIND_FOLDER) == "head");
    CHECK(job::layer_name_for("tiff", ISOMEND_IO_KIND_FOLDER) == "tiff");
    CHECK(job::layer_name_for("/data/ct.nrrd", ISOMEND_IO_KIND_NRRD) == "ct");
    CHECK(job::layer_name_for("/data/head/slices/s_%04d.tif", ISOMEND_IO_KIND_PATTERN) == "head");
    CHECK(job::layer_name_for("/data/knee/s_*.png", ISOMEND_IO_KIND_GLOB) == "knee");
    CHECK(job::layer_name_for("s_*.png", ISOMEND_IO_KIND_GLOB) == "s_*.png");
    CHECK(job::layer_name_for("/data/scan.v2.tif", ISOMEND_IO_KIND_MULTIPAGE) == "scan.v2");
    CHECK(job::layer_name_for("vol.raw", ISOMEND_IO_KIND_RAW) == "vol");
    CHECK(job::layer_name_for("/", ISOMEND_IO_KIND_FOLDER) == "isosurface");

    int64_t d[3] = {0, 0, 0};
    std::string msg;
    CHECK(job::parse_raw_dims("10 20 30", d, &msg) && d[0] == 10 && d[1] == 20 && d[2] == 30);
    CHECK(job::parse_raw_dims(" 4,5,6 ", d, &msg) && d[0] == 4 && d[1] == 5 && d[2] == 6);
    CHECK(job::parse_raw_dims("7x8x9", d, &msg) && d[0] == 7 && d[1] == 8 && d[2] == 9);
    const char *bad[] = {"", "10 20", "10 20 30 40", "10 -2 3", "a b c", "10 20 3.5", "0 1 2",
                         "99999999999999999999 1 1"};
    for (const char *b : bad) {
        msg.clear();
        CHECK(!job::parse_raw_dims(b, d, &msg));
        CHECK(contains(msg, "rawDims"));
    }
}

void test_run(const std::string &dir)
{
    const int nx = 21, ny = 18, nz = 17;
    const std::vector<uint16_t> v = make_volume(nx, ny, nz);
    const std::string path = dir + "/blobs.raw";
    FILE *f = std::fopen(path.c_str(), "wb");
    CHECK(f != nullptr);
    if (!f)
        return;
    CHECK_EQ_INT(std::fwrite(v.data(), sizeof(uint16_t), v.size(), f), v.size());
    std::fclose(f);

    const double iso = 700.5;
    const double unit[3] = {1, 1, 1};
    job::Params p = job::default_params();
    p.source = path;
    p.iso = iso;
    p.raw_dims = "21 18 17";
    p.raw_type_index = ISOMEND_U16;

    /* every method of the menu, padded and not: exactly the core's mesh */
    bool some_mending = false;
    const auto choices = job::method_choices();
    for (size_t mi = 0; mi < choices.size(); ++mi)
        for (int pad = 0; pad < 2; ++pad) {
            p.method_index = static_cast<int>(mi);
            p.pad = pad != 0;
            std::vector<int> seen;
            job::Job run;
            const bool ok = run.run(p, [&seen](int percent, const char *stage) {
                CHECK(stage && *stage);
                seen.push_back(percent);
                return true;
            });
            CHECK(ok);
            if (!ok) {
                std::fprintf(stderr, "run failed: %s\n", run.error().c_str());
                continue;
            }
            isomend_stats ref{};
            const unsigned flags = pad ? static_cast<unsigned>(ISOMEND_FLAG_PAD) : 0u;
            isomend_mesh *mesh = direct(v, nx, ny, nz, iso, choices[mi].method, flags, unit, &ref);
            check_same_mesh(run.mesh(), mesh);
            CHECK(std::memcmp(&ref.case_histogram, &run.stats().case_histogram,
                              sizeof ref.case_histogram) == 0);
            CHECK(std::memcmp(&ref.triangles_by_origin, &run.stats().triangles_by_origin,
                              sizeof ref.triangles_by_origin) == 0);
            if (choices[mi].method == ISOMEND_METHOD_DMC &&
                ref.triangles_by_origin[ISOMEND_ORIGIN_MEND] > 0)
                some_mending = true;
            isomend_mesh_destroy(mesh);

            CHECK(run.layer_name() == "blobs");
            bool counts_logged = false, histogram_logged = false;
            char counts[128];
            std::snprintf(counts, sizeof counts, "vertices %llu, triangles %llu",
                          static_cast<unsigned long long>(ref.vertices),
                          static_cast<unsigned long long>(ref.triangles));
            for (const std::string &line : run.log_lines()) {
                counts_logged = counts_logged || contains(line, counts);
                histogram_logged = histogram_logged || contains(line, " 14:");
            }
            CHECK(counts_logged);
            CHECK(histogram_logged);
            CHECK(!seen.empty());
            for (size_t i = 1; i < seen.size(); ++i)
                CHECK(seen[i] >= seen[i - 1]);
            if (!seen.empty())
                CHECK(seen.back() >= 95 && seen.back() <= 100 && seen.front() >= 0);
        }
    CHECK(some_mending); /* the volume exercises the mending */

    /* spacing: 0 keeps the source's (1 for raw), > 0 replaces it per axis */
    {
        p.method_index = 0;
        p.pad = true;
        p.spacing[0] = 0;
        p.spacing[1] = 0.5;
        p.spacing[2] = 2.25;
        job::Job run;
        CHECK(run.run(p, nullptr));
        const double sp[3] = {1, 0.5, 2.25};
        isomend_mesh *mesh = direct(v, nx, ny, nz, iso, ISOMEND_METHOD_DMC, ISOMEND_FLAG_PAD, sp,
                                    nullptr);
        check_same_mesh(run.mesh(), mesh);
        isomend_mesh_destroy(mesh);
        /* evenly spaced slices (issue 34): the geometry says so, at the z
         * spacing in use, and there is no warning */
        CHECK(run.geometry_known() && run.geometry().uniform);
        CHECK(run.warning().empty());
        bool geometry_logged = false;
        for (const std::string &line : run.log_lines())
            geometry_logged = geometry_logged || line == "slices evenly spaced, gap 2.25";
        CHECK(geometry_logged);
        p.spacing[0] = p.spacing[1] = p.spacing[2] = 0;
    }

    /* flipNormals: the core's flipped mesh */
    {
        p.flip_normals = true;
        job::Job run;
        CHECK(run.run(p, nullptr));
        isomend_mesh *mesh = direct(v, nx, ny, nz, iso, ISOMEND_METHOD_DMC,
                                    ISOMEND_FLAG_PAD | ISOMEND_FLAG_FLIP, unit, nullptr);
        check_same_mesh(run.mesh(), mesh);
        isomend_mesh_destroy(mesh);
        p.flip_normals = false;
    }

    /* post-processing (issue 37): clean-up, smoothing, decimation in the
     * command line's order, each exactly the core's call on the previous
     * result; the mesh stays closed; a log line per step */
    {
        job::Params q = p;
        q.min_component = 50;
        q.smooth_iterations = 5;
        q.decimate_ratio = 0.2;
        job::Job run;
        const bool ok = run.run(q, nullptr);
        CHECK(ok);
        if (!ok)
            std::fprintf(stderr, "post-processing run failed: %s\n", run.error().c_str());
        isomend_mesh *mesh =
            direct(v, nx, ny, nz, iso, ISOMEND_METHOD_DMC, ISOMEND_FLAG_PAD, unit, nullptr);
        const size_t plain = isomend_mesh_triangle_count(mesh);
        isomend_mesh *cleaned = nullptr, *smoothed = nullptr, *decimated = nullptr;
        isomend_clean_report cr{};
        isomend_decimate_report dr{};
        CHECK(isomend_mesh_clean(mesh, 50, 0, &cleaned, &cr) == ISOMEND_OK);
        CHECK(isomend_mesh_smooth(cleaned, 5, &smoothed, nullptr) == ISOMEND_OK);
        isomend_decimate_options d;
        isomend_decimate_options_init(&d);
        d.ratio = 0.2;
        CHECK(isomend_mesh_decimate(smoothed, &d, &decimated, &dr) == ISOMEND_OK);
        if (ok && decimated)
            check_same_mesh(run.mesh(), decimated);
        const job::PostReport &r = run.post_report();
        CHECK(r.cleaned && r.smoothed && r.decimated);
        CHECK(r.clean.components_before == cr.components_before &&
              r.clean.components_after == cr.components_after);
        CHECK(cr.components_before > cr.components_after); /* the blobs have small pieces */
        CHECK(r.decimate.triangles_after == dr.triangles_after);
        const size_t nt = ok ? isomend_mesh_triangle_count(run.mesh()) : 0;
        CHECK(nt > 0 && nt < plain / 4);
        /* closed: the padded surface has no hole edges before or after */
        isomend_check_report before{}, after{};
        CHECK(isomend_mesh_check(mesh, &before) == ISOMEND_OK);
        if (ok)
            CHECK(isomend_mesh_check(run.mesh(), &after) == ISOMEND_OK);
        CHECK(before.hole_edges == 0 && after.hole_edges == 0);
        bool clean_logged = false, smooth_logged = false, decimate_logged = false;
        for (const std::string &line : run.log_lines()) {
            clean_logged = clean_logged || contains(line, "clean-up");
            smooth_logged = smooth_logged || contains(line, "smoothing (5 iterations)");
            decimate_logged = decimate_logged || (contains(line, "decimation (ratio 0.2)") &&
                                                  contains(line, "largest error"));
        }
        CHECK(clean_logged && smooth_logged && decimate_logged);
        isomend_mesh_destroy(decimated);
        isomend_mesh_destroy(smoothed);
        isomend_mesh_destroy(cleaned);
        isomend_mesh_destroy(mesh);

        /* off by default: the plain run has no post-processing line */
        job::Job plain_run;
        CHECK(plain_run.run(p, nullptr));
        const job::PostReport &pr = plain_run.post_report();
        CHECK(!pr.cleaned && !pr.smoothed && !pr.decimated);
        for (const std::string &line : plain_run.log_lines())
            CHECK(!contains(line, "decimation") && !contains(line, "smoothing"));

        /* a minimum above every component: an error, no mesh */
        job::Params big = p;
        big.min_component = 100000000;
        job::Job none;
        CHECK(!none.run(big, nullptr));
        CHECK(none.mesh() == nullptr && contains(none.error(), "minComponent"));
    }

    /* cancellation from the progress callback: no mesh */
    {
        job::Job run;
        CHECK(!run.run(p, [](int percent, const char *) { return percent < 10; }));
        CHECK(run.mesh() == nullptr);
        CHECK(contains(run.error(), "cancelled"));
    }

    /* no surface at this level: an error with the value range, no mesh */
    {
        job::Params q = p;
        q.iso = 1e6;
        job::Job run;
        CHECK(!run.run(q, nullptr));
        CHECK(run.mesh() == nullptr);
        CHECK(contains(run.error(), "iso:") && contains(run.error(), "range"));
    }

    /* a raw file whose size does not match rawDims: the io message */
    {
        job::Params q = p;
        q.raw_dims = "21 18 18";
        job::Job run;
        CHECK(!run.run(q, nullptr));
        CHECK(run.mesh() == nullptr);
        CHECK(contains(run.error(), "blobs.raw"));
    }
}

void test_errors(const std::string &dir)
{
    struct Case {
        const char *what;
        void (*change)(job::Params &);
        const char *expect;
    };
    static std::string missing;
    missing = dir + "/no_such_folder";
    const Case cases[] = {
        {"empty source", [](job::Params &q) { q.source = "  "; }, "source:"},
        {"missing folder", [](job::Params &q) { q.source = missing; }, "no_such_folder"},
        {"NaN iso", [](job::Params &q) { q.iso = std::nan(""); }, "iso:"},
        {"infinite iso", [](job::Params &q) { q.iso = HUGE_VAL; }, "iso:"},
        {"method index", [](job::Params &q) { q.method_index = 99; }, "method:"},
        {"negative method", [](job::Params &q) { q.method_index = -1; }, "method:"},
        {"negative spacingY", [](job::Params &q) { q.spacing[1] = -1; }, "spacingY"},
        {"NaN spacingZ", [](job::Params &q) { q.spacing[2] = std::nan(""); }, "spacingZ"},
        {"channel", [](job::Params &q) { q.channel = -3; }, "channel:"},
        {"rawDims", [](job::Params &q) { q.raw_dims = "12 x"; }, "rawDims"},
        {"rawType",
         [](job::Params &q) {
             q.raw_dims = "2 2 2";
             q.raw_type_index = 42;
         },
         "rawType"},
        {"minComponent", [](job::Params &q) { q.min_component = -1; }, "minComponent:"},
        {"smoothIterations", [](job::Params &q) { q.smooth_iterations = -2; }, "smoothIterations:"},
        {"too many iterations", [](job::Params &q) { q.smooth_iterations = 10001; },
         "smoothIterations:"},
        {"decimateRatio > 1", [](job::Params &q) { q.decimate_ratio = 1.5; }, "decimateRatio:"},
        {"NaN decimateRatio", [](job::Params &q) { q.decimate_ratio = std::nan(""); },
         "decimateRatio:"},
    };
    for (const Case &c : cases) {
        job::Params q = job::default_params();
        q.source = dir;
        c.change(q);
        job::Job run;
        const bool ok = run.run(q, nullptr);
        CHECK(!ok);
        CHECK(run.mesh() == nullptr);
        if (!contains(run.error(), c.expect)) {
            std::fprintf(stderr, "%s: expected \"%s\" in \"%s\"\n", c.what, c.expect,
                         run.error().c_str());
            CHECK(false);
        }
    }
}

/* A label map: two touching boxes (1, 2), a ball (7), background 0. */
std::vector<uint16_t> make_labels(int nx, int ny, int nz)
{
    std::vector<uint16_t> v(static_cast<size_t>(nx) * ny * nz, 0);
    for (int z = 0; z < nz; ++z)
        for (int y = 0; y < ny; ++y)
            for (int x = 0; x < nx; ++x) {
                uint16_t l = 0;
                if (x >= 2 && x < 9 && y >= 3 && y < 12 && z >= 2 && z < 10)
                    l = 1;
                else if (x >= 9 && x < 15 && y >= 3 && y < 12 && z >= 2 && z < 10)
                    l = 2;
                else if (std::hypot(std::hypot(x - 12.2, y - 12.4), z - 11.7) < 3.6)
                    l = 7;
                v[(static_cast<size_t>(z) * ny + y) * nx + x] = l;
            }
    return v;
}

bool write_file(const std::string &path, const std::string &head, const void *data, size_t bytes)
{
    FILE *f = std::fopen(path.c_str(), "wb");
    if (!f)
        return false;
    bool ok = std::fwrite(head.data(), 1, head.size(), f) == head.size() &&
              (!bytes || std::fwrite(data, 1, bytes, f) == bytes);
    return std::fclose(f) == 0 && ok;
}

void test_labels(const std::string &dir)
{
    const int nx = 18, ny = 17, nz = 16;
    const std::vector<uint16_t> v = make_labels(nx, ny, nz);
    const std::string seg = dir + "/organs.seg.nrrd", raw = dir + "/organs.raw";
    const std::string header =
        "NRRD0004\ntype: uint16\ndimension: 3\nsizes: 18 17 16\nspacings: 0.5 0.5 1.5\n"
        "endian: little\nencoding: raw\n"
        "Segment0_Name:=Liver\nSegment0_Color:=1 0 0\nSegment0_LabelValue:=1\n"
        "Segment1_Name:=Left kidney\nSegment1_Color:=0 0.5 1\nSegment1_LabelValue:=2\n"
        "Segment2_Name:=Tumour\nSegment2_Color:=1 1 0\nSegment2_LabelValue:=7\n\n";
    CHECK(write_file(seg, header, v.data(), v.size() * 2));
    CHECK(write_file(raw, "", v.data(), v.size() * 2));

    /* the core's mesh of each label's indicator, for comparison */
    auto indicator = [&](int64_t label, const double spacing[3]) {
        std::vector<uint8_t> ind(v.size());
        for (size_t i = 0; i < v.size(); ++i)
            ind[i] = v[i] == label;
        return direct(ind, nx, ny, nz, 0.5, ISOMEND_METHOD_DMC, ISOMEND_FLAG_PAD, spacing, nullptr);
    };

    /* every label of the .seg.nrrd: its names and colours */
    job::Params p = job::default_params();
    p.source = seg;
    p.labels = " all ";
    job::Job run;
    std::vector<int> seen;
    CHECK(run.run(p, [&seen](int percent, const char *) {
        seen.push_back(percent);
        return true;
    }));
    if (!run.error().empty())
        std::fprintf(stderr, "labels run: %s\n", run.error().c_str());
    CHECK(run.mesh() == nullptr);
    CHECK(std::is_sorted(seen.begin(), seen.end()));
    const double sp[3] = {0.5, 0.5, 1.5};
    const struct {
        int64_t value;
        const char *name;
        uint8_t rgb[3];
    } want[] = {
        {1, "Liver", {255, 0, 0}}, {2, "Left kidney", {0, 128, 255}}, {7, "Tumour", {255, 255, 0}}};
    CHECK_EQ_INT(run.labels().size(), 3);
    for (size_t q = 0; q < run.labels().size() && q < 3; ++q) {
        const job::LabelLayer &l = run.labels()[q];
        CHECK_EQ_INT(l.value, want[q].value);
        CHECK(l.name == want[q].name);
        CHECK(std::memcmp(l.rgb, want[q].rgb, 3) == 0);
        isomend_mesh *ref = indicator(l.value, sp);
        check_same_mesh(l.mesh, ref);
        isomend_check_report rep;
        CHECK_EQ_INT(isomend_mesh_check(l.mesh, &rep), ISOMEND_OK);
        CHECK_EQ_INT(rep.hole_edges + rep.nonmanifold_edges + rep.misoriented_edges, 0);
        isomend_mesh_destroy(ref);
        bool logged = false;
        for (const std::string &line : run.log_lines())
            logged |= contains(line, ("\"" + std::string(want[q].name) + "\"").c_str());
        CHECK(logged);
    }
    bool names_logged = false;
    for (const std::string &line : run.log_lines())
        names_logged |= contains(line, "names from seg.nrrd");
    CHECK(names_logged);

    /* two labels of the raw file, names from a colour table, then none */
    const std::string table = dir + "/organs.txt";
    const std::string lut = "# FreeSurfer-style\n2 Kidney 10 20 30 0\n7 Lesion 200 100 50 0\n";
    CHECK(write_file(table, lut, nullptr, 0));
    p = job::default_params();
    p.source = raw;
    p.raw_dims = "18 17 16";
    p.raw_type_index = ISOMEND_U16;
    p.labels = "7, 2";
    p.label_table = table;
    p.method_index = 1; /* Original MC: also taken */
    CHECK(run.run(p, nullptr));
    CHECK_EQ_INT(run.labels().size(), 2);
    if (run.labels().size() == 2) {
        CHECK_EQ_INT(run.labels()[0].value, 7);
        CHECK(run.labels()[0].name == "Lesion");
        CHECK(run.labels()[1].name == "Kidney");
        const uint8_t c[3] = {10, 20, 30};
        CHECK(std::memcmp(run.labels()[1].rgb, c, 3) == 0);
    }
    p.label_table.clear();
    p.method_index = 0;
    CHECK(run.run(p, nullptr));
    CHECK_EQ_INT(run.labels().size(), 2);
    if (run.labels().size() == 2) {
        CHECK(run.labels()[0].name == "label_7");
        uint8_t c[3];
        isomend_io_label_name(nullptr, 7, nullptr, 0, c);
        CHECK(std::memcmp(run.labels()[0].rgb, c, 3) == 0);
        const double unit[3] = {1, 1, 1};
        isomend_mesh *ref = indicator(7, unit);
        check_same_mesh(run.labels()[0].mesh, ref);
        isomend_mesh_destroy(ref);
    }

    /* refusals: each names its parameter or the reason, and leaves no layer */
    std::vector<float> fv(v.begin(), v.end());
    fv[100] = 0.5f;
    const std::string fraw = dir + "/fractions.raw";
    CHECK(write_file(fraw, "", fv.data(), fv.size() * 4));
    static std::string s_raw, s_seg, s_fraw, s_missing;
    s_raw = raw, s_seg = seg, s_fraw = fraw, s_missing = dir + "/none.ctbl";
    struct Case {
        const char *what;
        void (*change)(job::Params &);
        const char *expect;
    };
    const Case cases[] = {
        {"twice", [](job::Params &q) { q.labels = "1,2,1"; }, "labels: label 1 is listed twice"},
        {"not a number", [](job::Params &q) { q.labels = "1,x"; }, "labels:"},
        {"all and more", [](job::Params &q) { q.labels = "all,3"; }, "labels:"},
        {"absent", [](job::Params &q) { q.labels = "1,9"; }, "label 9 is not in"},
        {"post-processing", [](job::Params &q) { q.smooth_iterations = 3; }, "does not apply"},
        {"table alone",
         [](job::Params &q) {
             q.labels.clear();
             q.label_table = s_missing;
         },
         "labelTable: only with labels"},
        {"missing table", [](job::Params &q) { q.label_table = s_missing; }, "none.ctbl"},
        {"fractions",
         [](job::Params &q) {
             q.source = s_fraw;
             q.raw_type_index = ISOMEND_F32;
         },
         "non-integer sample 0.5"},
    };
    for (const Case &c : cases) {
        job::Params q = job::default_params();
        q.source = s_raw;
        q.raw_dims = "18 17 16";
        q.raw_type_index = ISOMEND_U16;
        q.labels = "all";
        c.change(q);
        job::Job bad;
        CHECK(!bad.run(q, nullptr));
        CHECK(bad.labels().empty() && bad.mesh() == nullptr);
        if (!contains(bad.error(), c.expect)) {
            std::fprintf(stderr, "%s: expected \"%s\" in \"%s\"\n", c.what, c.expect,
                         bad.error().c_str());
            CHECK(false);
        }
    }
    /* a method a label map does not take (the menu's 4th entry, when built) */
    if (job::method_choices().size() > 3) {
        job::Params q = job::default_params();
        q.source = s_seg;
        q.labels = "all";
        q.method_index = 3;
        job::Job bad;
        CHECK(!bad.run(q, nullptr));
        CHECK(contains(bad.error(), "method: a label map takes"));
    }
}

} // namespace

int main(int argc, char **argv)
{
    /* --methods: the method menu as the plugin builds it (index, core name,
     * display name), for test_meshlab.py's "methods" test. */
    if (argc == 2 && std::strcmp(argv[1], "--methods") == 0) {
        const auto choices = job::method_choices();
        for (size_t i = 0; i < choices.size(); ++i)
            std::printf("%zu\t%s\t%s\n", i, isomend_method_name(choices[i].method),
                        choices[i].display.c_str());
        return 0;
    }
    TempDir dir;
    CHECK(!dir.path.empty());
    if (dir.path.empty())
        return 1;
    test_lists();
    test_parsing();
    test_run(dir.path);
    test_errors(dir.path);
    test_labels(dir.path);
    TEST_EXIT();
}
