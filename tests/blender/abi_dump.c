/*
 * abi_dump.c - prints, as JSON, the sizes and field offsets of the public
 * structs of isomend.h and isomend_io.h and the values of their enums, so
 * that test_wrapper.py can compare them with the ctypes declarations of
 * blender_addon/isomend_import/isomend.py.  A field added to a struct or an
 * enum renumbered in a header then fails a test instead of corrupting memory.
 */
#include <stddef.h>
#include <stdio.h>

#include "isomend.h"
#include "isomend_io.h"

#define FIELD(type, name) printf("      \"%s\": %zu,\n", #name, offsetof(type, name))
#define LAST_FIELD(type, name) printf("      \"%s\": %zu\n", #name, offsetof(type, name))
#define CONST(name) printf("    \"%s\": %lld,\n", #name, (long long)(name))
#define LAST_CONST(name) printf("    \"%s\": %lld\n", #name, (long long)(name))

static void begin_struct(const char *name, size_t size, int first)
{
    printf("%s    \"%s\": {\"size\": %zu, \"offsets\": {\n", first ? "" : ",\n", name, size);
}

static void end_struct(void)
{
    printf("    }}");
}

int main(void)
{
    printf("{\n  \"structs\": {\n");
    begin_struct("Volume", sizeof(isomend_volume), 1);
    FIELD(isomend_volume, data);
    FIELD(isomend_volume, type);
    FIELD(isomend_volume, dims);
    FIELD(isomend_volume, strides);
    FIELD(isomend_volume, spacing);
    FIELD(isomend_volume, origin);
    LAST_FIELD(isomend_volume, slice_origins);
    end_struct();
    begin_struct("Options", sizeof(isomend_options), 0);
    FIELD(isomend_options, iso);
    FIELD(isomend_options, method);
    FIELD(isomend_options, flags);
    FIELD(isomend_options, threads);
    FIELD(isomend_options, progress);
    LAST_FIELD(isomend_options, progress_user);
    end_struct();
    begin_struct("Stats", sizeof(isomend_stats), 0);
    FIELD(isomend_stats, cubes);
    FIELD(isomend_stats, case_histogram);
    FIELD(isomend_stats, ambiguous_faces);
    FIELD(isomend_stats, inverted_combinations);
    FIELD(isomend_stats, triangles_by_origin);
    FIELD(isomend_stats, nan_samples);
    FIELD(isomend_stats, vertices);
    LAST_FIELD(isomend_stats, triangles);
    end_struct();
    begin_struct("CheckReport", sizeof(isomend_check_report), 0);
    FIELD(isomend_check_report, vertices);
    FIELD(isomend_check_report, triangles);
    FIELD(isomend_check_report, edges);
    FIELD(isomend_check_report, border_edges);
    FIELD(isomend_check_report, hole_edges);
    FIELD(isomend_check_report, hole_loops);
    FIELD(isomend_check_report, nonmanifold_edges);
    FIELD(isomend_check_report, misoriented_edges);
    FIELD(isomend_check_report, nonmanifold_vertices);
    FIELD(isomend_check_report, degenerate_triangles);
    FIELD(isomend_check_report, components);
    LAST_FIELD(isomend_check_report, euler);
    end_struct();
    begin_struct("DecimateOptions", sizeof(isomend_decimate_options), 0);
    FIELD(isomend_decimate_options, ratio);
    FIELD(isomend_decimate_options, target_triangles);
    LAST_FIELD(isomend_decimate_options, max_error);
    end_struct();
    begin_struct("DecimateReport", sizeof(isomend_decimate_report), 0);
    FIELD(isomend_decimate_report, triangles_before);
    FIELD(isomend_decimate_report, triangles_after);
    FIELD(isomend_decimate_report, vertices_before);
    FIELD(isomend_decimate_report, vertices_after);
    FIELD(isomend_decimate_report, target_triangles);
    FIELD(isomend_decimate_report, reached);
    FIELD(isomend_decimate_report, max_error);
    FIELD(isomend_decimate_report, mean_error);
    FIELD(isomend_decimate_report, collapses);
    FIELD(isomend_decimate_report, locked_vertices);
    FIELD(isomend_decimate_report, refused_topology);
    FIELD(isomend_decimate_report, refused_geometry);
    LAST_FIELD(isomend_decimate_report, refused_error);
    end_struct();
    begin_struct("SmoothReport", sizeof(isomend_smooth_report), 0);
    FIELD(isomend_smooth_report, moved_vertices);
    FIELD(isomend_smooth_report, volume_before);
    FIELD(isomend_smooth_report, volume_after);
    LAST_FIELD(isomend_smooth_report, max_displacement);
    end_struct();
    begin_struct("CleanReport", sizeof(isomend_clean_report), 0);
    FIELD(isomend_clean_report, components_before);
    FIELD(isomend_clean_report, components_after);
    FIELD(isomend_clean_report, triangles_removed);
    LAST_FIELD(isomend_clean_report, vertices_removed);
    end_struct();
    begin_struct("IOOptions", sizeof(isomend_io_options), 0);
    FIELD(isomend_io_options, first);
    FIELD(isomend_io_options, count);
    FIELD(isomend_io_options, step);
    FIELD(isomend_io_options, channel);
    FIELD(isomend_io_options, spacing);
    FIELD(isomend_io_options, origin);
    FIELD(isomend_io_options, threads);
    FIELD(isomend_io_options, memory_limit);
    FIELD(isomend_io_options, raw_dims);
    FIELD(isomend_io_options, raw_type);
    FIELD(isomend_io_options, raw_header);
    FIELD(isomend_io_options, raw_big_endian);
    FIELD(isomend_io_options, progress);
    FIELD(isomend_io_options, progress_user);
    FIELD(isomend_io_options, slice_positions);
    LAST_FIELD(isomend_io_options, slice_position_count);
    end_struct();
    begin_struct("IOSummary", sizeof(isomend_io_summary), 0);
    FIELD(isomend_io_summary, min);
    FIELD(isomend_io_summary, max);
    FIELD(isomend_io_summary, samples);
    FIELD(isomend_io_summary, nan_samples);
    FIELD(isomend_io_summary, histogram);
    FIELD(isomend_io_summary, suggested_iso);
    LAST_FIELD(isomend_io_summary, read_seconds);
    end_struct();
    begin_struct("IOSeries", sizeof(isomend_io_series), 0);
    FIELD(isomend_io_series, size);
    FIELD(isomend_io_series, uid);
    FIELD(isomend_io_series, description);
    FIELD(isomend_io_series, modality);
    FIELD(isomend_io_series, number);
    FIELD(isomend_io_series, files);
    FIELD(isomend_io_series, images);
    FIELD(isomend_io_series, columns);
    LAST_FIELD(isomend_io_series, rows);
    end_struct();
    begin_struct("IODicom", sizeof(isomend_io_dicom), 0);
    FIELD(isomend_io_dicom, size);
    FIELD(isomend_io_dicom, modality);
    FIELD(isomend_io_dicom, series_uid);
    FIELD(isomend_io_dicom, description);
    FIELD(isomend_io_dicom, transfer_syntax);
    FIELD(isomend_io_dicom, transfer_syntax_name);
    FIELD(isomend_io_dicom, photometric);
    FIELD(isomend_io_dicom, bits_stored);
    FIELD(isomend_io_dicom, pixel_signed);
    FIELD(isomend_io_dicom, rescaled);
    FIELD(isomend_io_dicom, hounsfield);
    FIELD(isomend_io_dicom, rescale_slope);
    FIELD(isomend_io_dicom, rescale_intercept);
    FIELD(isomend_io_dicom, orientation);
    FIELD(isomend_io_dicom, normal);
    FIELD(isomend_io_dicom, position);
    FIELD(isomend_io_dicom, files);
    FIELD(isomend_io_dicom, multiframe);
    FIELD(isomend_io_dicom, non_image);
    FIELD(isomend_io_dicom, non_dicom);
    FIELD(isomend_io_dicom, other_series);
    LAST_FIELD(isomend_io_dicom, axes);
    end_struct();
    begin_struct("IOGeometry", sizeof(isomend_io_geometry), 0);
    FIELD(isomend_io_geometry, size);
    FIELD(isomend_io_geometry, uniform);
    FIELD(isomend_io_geometry, gap_median);
    FIELD(isomend_io_geometry, gap_min);
    FIELD(isomend_io_geometry, gap_max);
    FIELD(isomend_io_geometry, tilt_degrees);
    FIELD(isomend_io_geometry, max_offset);
    FIELD(isomend_io_geometry, long_gaps);
    FIELD(isomend_io_geometry, uneven_gaps);
    LAST_FIELD(isomend_io_geometry, warning);
    end_struct();
    printf("\n  },\n  \"constants\": {\n");
    CONST(ISOMEND_ERR_CANCELLED);
    CONST(ISOMEND_ERR_UNSUPPORTED);
    CONST(ISOMEND_U8);
    CONST(ISOMEND_I8);
    CONST(ISOMEND_U16);
    CONST(ISOMEND_I16);
    CONST(ISOMEND_I32);
    CONST(ISOMEND_F32);
    CONST(ISOMEND_F64);
    CONST(ISOMEND_U32);
    CONST(ISOMEND_TYPE_COUNT);
    CONST(ISOMEND_METHOD_MC);
    CONST(ISOMEND_METHOD_DURST);
    CONST(ISOMEND_METHOD_DMC);
    CONST(ISOMEND_METHOD_COUNT);
    CONST(ISOMEND_FLAG_NO_NORMALS);
    CONST(ISOMEND_FLAG_FLIP);
    CONST(ISOMEND_FLAG_PAD);
    CONST(ISOMEND_FLAG_NO_ORIGINS);
    CONST(ISOMEND_FLAG_SMALL_PAGES);
    CONST(ISOMEND_ORIGIN_TABLE);
    CONST(ISOMEND_ORIGIN_DURST);
    CONST(ISOMEND_ORIGIN_MEND);
    CONST(ISOMEND_IO_ERR_CANCELLED);
    CONST(ISOMEND_IO_ERR_INTERNAL);
    CONST(ISOMEND_IO_CHANNEL_AUTO);
    CONST(ISOMEND_IO_CHANNEL_LUMA);
    CONST(ISOMEND_IO_STAGE_OPEN);
    CONST(ISOMEND_IO_STAGE_READ);
    CONST(ISOMEND_IO_STAGE_ANALYSE);
    CONST(ISOMEND_IO_STAGE_EXTRACT);
    CONST(ISOMEND_IO_KIND_NRRD);
    CONST(ISOMEND_IO_KIND_DICOM);
    CONST(ISOMEND_IO_ERR_SERIES);
    CONST(ISOMEND_IO_AXES_PATIENT);
    CONST(ISOMEND_IO_AXES_GRID);
    CONST(ISOMEND_IO_LEVEL_OTSU);
    CONST(ISOMEND_IO_LEVEL_BONE);
    CONST(ISOMEND_IO_LEVEL_SKIN);
    LAST_CONST(ISOMEND_IO_HISTOGRAM_BINS);
    printf("  }\n}\n");
    return 0;
}
