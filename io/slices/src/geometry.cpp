// geometry.cpp - where the slices are: gaps, tilt, the evenly spaced grid or
// the table of slice origins (isomend_volume.slice_origins), and the one-line
// warning about uneven gaps.
//
// Every source ends up with a list of slice origins in the frame of the
// volume isomend_io_load() describes: a DICOM series' from its Image Position
// (Patient) values turned into its own frame (dicom.cpp), a stack's or raw
// volume's from options.slice_positions (api.cpp).  measure_slices() compares
// them with the evenly spaced grid through the first and the last origin
// (origin0 + k * mean gap along z): within the caller's tolerance everywhere
// the grid is uniform and the table is dropped (the volume keeps its origin
// and spacing, byte for byte what it was before slice origins existed);
// otherwise the table stays and the core meshes each slice where it is.
// Gaps are measured along z (the slice normal); the median is the upper
// middle gap, as the DICOM reader has always measured it.
#include "internal.hpp"

#include <algorithm>
#include <cmath>
#include <cstdio>

namespace isomend_io {

namespace {

constexpr double kUnevenGap = 0.01; // of the median gap
constexpr double kLongGap = 1.5;    // times the median gap

std::string num4(double v) {
    char b[64];
    std::snprintf(b, sizeof b, "%.4g", v);
    return b;
}

} // namespace

void measure_slices(std::vector<double> origins, double tolerance, SliceGeometry &g) {
    g = SliceGeometry{};
    const size_t n = origins.size() / 3;
    if (n < 2) return;
    const double *o = origins.data();
    const double mean = (o[3 * (n - 1) + 2] - o[2]) / (double)(n - 1);
    std::vector<double> gaps(n - 1);
    for (size_t k = 0; k + 1 < n; k++) gaps[k] = o[3 * (k + 1) + 2] - o[3 * k + 2];
    std::vector<double> sorted = gaps;
    std::nth_element(sorted.begin(), sorted.begin() + (long)(sorted.size() / 2), sorted.end());
    g.gap_median = sorted[sorted.size() / 2];
    g.gap_min = *std::min_element(gaps.begin(), gaps.end());
    g.gap_max = *std::max_element(gaps.begin(), gaps.end());
    for (size_t k = 0; k < gaps.size(); k++) {
        if (std::fabs(gaps[k] - g.gap_median) > kUnevenGap * g.gap_median) g.uneven_gaps++;
        if (gaps[k] > kLongGap * g.gap_median) {
            g.long_gaps++;
            if (g.longest < 0 || gaps[k] > gaps[(size_t)g.longest]) g.longest = (int64_t)k;
        }
    }
    for (size_t k = 0; k < n; k++) {
        double dx = o[3 * k] - o[0], dy = o[3 * k + 1] - o[1],
               dz = o[3 * k + 2] - (o[2] + (double)k * mean);
        g.max_offset = std::max(g.max_offset, std::sqrt(dx * dx + dy * dy + dz * dz));
    }
    const double *last = o + 3 * (n - 1);
    g.tilt_degrees =
        std::atan2(std::hypot(last[0] - o[0], last[1] - o[1]), last[2] - o[2]) * 180.0 / M_PI;
    g.uniform = g.max_offset <= tolerance;
    if (!g.uniform) g.origins = std::move(origins);
}

void measure_uniform(double gap, SliceGeometry &g) {
    g = SliceGeometry{};
    g.gap_median = g.gap_min = g.gap_max = gap;
}

std::string gap_warning(const SliceGeometry &g, const std::string &meshed,
                        const std::function<std::string(int64_t)> &slice_name) {
    if (!g.uneven_gaps && !g.long_gaps) return "";
    std::string w = "slice gaps vary from " + num4(g.gap_min) + " to " + num4(g.gap_max) +
                    " mm (median " + num4(g.gap_median) + " mm): " + meshed;
    if (g.long_gaps > 0 && g.longest >= 0) {
        const int64_t k = g.longest;
        const double ratio = g.gap_max / g.gap_median;
        const std::string between = " between slice " + slice_name(k) + " and " + slice_name(k + 1);
        if (g.long_gaps == 1)
            w += "; a gap of " + num4(g.gap_max) + " mm" + between + " is " + num4(ratio) +
                 "x the median: a missing slice?";
        else
            w += "; " + std::to_string(g.long_gaps) + " gaps over 1.5x the median, the longest " +
                 num4(g.gap_max) + " mm" + between + " (" + num4(ratio) + "x): missing slices?";
    }
    return w;
}

} // namespace isomend_io
