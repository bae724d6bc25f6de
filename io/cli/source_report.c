/*
 * source_report.c - what a DICOM series or a NIfTI volume says about itself,
 * for `info` (text lines) and the --json objects of `info` and `extract`
 *
 * A DICOM series: its modality, description, files and what was ignored,
 * the values (bits, sign, photometric, rescale, Hounsfield units), the
 * orientation and position, the axes the mesh is in and, for CT in HU, the
 * named levels; a folder of several series: the list.  A NIfTI volume: its
 * version, datatype, scaling and the transform used (sform, qform or
 * pixdim) with its matrix.  Everything comes from the importer; without it
 * (ISOMEND_HAVE_IO undefined) the text functions print nothing and the JSON
 * ones null (or an empty list).
 */
#define _POSIX_C_SOURCE 200809L

#include "source_internal.h"

#include <string.h>

#ifdef ISOMEND_HAVE_IO
/* `, "key": "value"` (or without the comma for the first member) */
static void json_text_member(FILE *fp, int first, const char *key, const char *value)
{
    fprintf(fp, "%s\"%s\": ", first ? "" : ", ", key);
    cli_json_string(fp, value);
}

static int dicom_of(const cli_source *s, isomend_io_dicom *d)
{
    memset(d, 0, sizeof *d);
    d->size = sizeof *d;
    return s->io && s->dicom && !s->series_listed &&
           cli_io.dicom_info((const isomend_io_source *)s->io, d) == ISOMEND_IO_OK;
}

/* The importer's named levels of a CT series, indexed by isomend_io_level. */
static int levels_of(cli_source *s, double lv[3])
{
    for (int l = ISOMEND_IO_LEVEL_OTSU; l <= ISOMEND_IO_LEVEL_SKIN; l++)
        if (cli_io.level_value((isomend_io_source *)s->io, l, &lv[l]) != ISOMEND_IO_OK)
            return 0;
    return 1;
}
#endif

void cli_print_series(FILE *fp, const cli_source *s)
{
#ifdef ISOMEND_HAVE_IO
    if (!s->io) return;
    const isomend_io_source *io = (const isomend_io_source *)s->io;
    int64_t n = cli_io.series_count(io), chosen = cli_io.series_chosen(io);
    if (n < 2 && !s->series_listed) return;
    fprintf(fp, "  series:      %lld%s\n", (long long)n,
            s->series_listed ? "; choose one with --series N or --series UID" : "");
    for (int64_t i = 0; i < n; i++) {
        isomend_io_series e;
        memset(&e, 0, sizeof e);
        e.size = sizeof e;
        if (cli_io.series_get(io, i, &e) != ISOMEND_IO_OK) continue;
        fprintf(fp, "  %s %3lld: %-4s \"%s\"", i == chosen ? "*" : " ", (long long)(i + 1),
                e.modality[0] ? e.modality : "?", e.description);
        if (e.number >= 0) fprintf(fp, ", series number %lld", (long long)e.number);
        fprintf(fp, ", %lld x %lld, %lld images in %lld files, UID %s\n", (long long)e.columns,
                (long long)e.rows, (long long)e.images, (long long)e.files, e.uid);
    }
#else
    (void)fp;
    (void)s;
#endif
}

void cli_json_series(FILE *fp, const cli_source *s)
{
    fprintf(fp, "[");
#ifdef ISOMEND_HAVE_IO
    if (s->io) {
        const isomend_io_source *io = (const isomend_io_source *)s->io;
        int64_t n = cli_io.series_count(io);
        for (int64_t i = 0; i < n; i++) {
            isomend_io_series e;
            memset(&e, 0, sizeof e);
            e.size = sizeof e;
            if (cli_io.series_get(io, i, &e) != ISOMEND_IO_OK) continue;
            fprintf(fp, "%s{\"index\": %lld", i ? ", " : "", (long long)(i + 1));
            json_text_member(fp, 0, "uid", e.uid);
            json_text_member(fp, 0, "description", e.description);
            json_text_member(fp, 0, "modality", e.modality);
            fprintf(fp, ", \"number\": %lld, \"files\": %lld, \"images\": %lld, \"columns\": %lld, "
                        "\"rows\": %lld}",
                    (long long)e.number, (long long)e.files, (long long)e.images,
                    (long long)e.columns, (long long)e.rows);
        }
    }
#else
    (void)s;
#endif
    fprintf(fp, "]");
}

void cli_print_dicom(FILE *fp, cli_source *s)
{
#ifdef ISOMEND_HAVE_IO
    isomend_io_dicom d;
    if (!dicom_of(s, &d)) return;
    fprintf(fp, "  dicom:       %s \"%s\", %lld file%s%s, %s\n", d.modality[0] ? d.modality : "?",
            d.description, (long long)d.files, d.files == 1 ? "" : "s",
            d.multiframe ? " (multi-frame)" : "", d.transfer_syntax_name);
    fprintf(fp, "  ignored:     %lld DICOM object%s without pixel data, %lld file%s not DICOM, "
                "%lld file%s of other series\n",
            (long long)d.non_image, d.non_image == 1 ? "" : "s", (long long)d.non_dicom,
            d.non_dicom == 1 ? "" : "s", (long long)d.other_series, d.other_series == 1 ? "" : "s");
    cli_print_series(fp, s);
    fprintf(fp, "  values:      %d-bit %s %s", d.bits_stored, d.pixel_signed ? "signed" : "unsigned",
            d.photometric);
    if (strcmp(d.photometric, "MONOCHROME1") == 0) fprintf(fp, " (inverted: brighter is higher)");
    if (d.rescaled)
        fprintf(fp, ", rescaled: slope %g, intercept %g%s", d.rescale_slope, d.rescale_intercept,
                d.hounsfield ? " (HU)" : "");
    fputc('\n', fp);
    fprintf(fp, "  orientation: row %g, %g, %g; column %g, %g, %g; normal %g, %g, %g\n",
            d.orientation[0], d.orientation[1], d.orientation[2], d.orientation[3],
            d.orientation[4], d.orientation[5], d.normal[0], d.normal[1], d.normal[2]);
    fprintf(fp, "  position:    %g, %g, %g (slice 0, patient LPS mm)\n", d.position[0],
            d.position[1], d.position[2]);
    if (d.axes == ISOMEND_IO_AXES_GRID)
        fprintf(fp, "  axes:        grid (--grid-axes): x along the rows, y along the columns, z along "
                    "the slices, not rotated into patient space\n");
    else if (s->has_world)
        fprintf(fp, "  axes:        patient (LPS mm): the mesh is turned by the direction cosines "
                    "(world = position + R * index * spacing)\n");
    else
        fprintf(fp, "  axes:        patient (LPS mm): x to the patient's left, y posterior, z head\n");
    double lv[3];
    if (d.hounsfield && levels_of(s, lv))
        fprintf(fp, "  levels (HU): bone %.9g, skin %.9g, Otsu %.9g; extract uses bone unless --iso "
                    "skin|otsu|VALUE\n", lv[ISOMEND_IO_LEVEL_BONE], lv[ISOMEND_IO_LEVEL_SKIN],
                lv[ISOMEND_IO_LEVEL_OTSU]);
#else
    (void)fp;
    (void)s;
#endif
}

void cli_json_dicom(FILE *fp, cli_source *s)
{
#ifdef ISOMEND_HAVE_IO
    isomend_io_dicom d;
    if (!dicom_of(s, &d)) {
        fprintf(fp, "null");
        return;
    }
    fputc('{', fp);
    json_text_member(fp, 1, "modality", d.modality);
    json_text_member(fp, 0, "series_uid", d.series_uid);
    json_text_member(fp, 0, "description", d.description);
    json_text_member(fp, 0, "transfer_syntax", d.transfer_syntax);
    json_text_member(fp, 0, "photometric", d.photometric);
    fprintf(fp, ", \"bits_stored\": %d, \"signed\": %s, \"rescaled\": %s, \"rescale_slope\": %.17g, "
                "\"rescale_intercept\": %.17g, \"hounsfield\": %s",
            d.bits_stored, d.pixel_signed ? "true" : "false", d.rescaled ? "true" : "false",
            d.rescale_slope, d.rescale_intercept, d.hounsfield ? "true" : "false");
    fprintf(fp, ", \"orientation\": [%.17g, %.17g, %.17g, %.17g, %.17g, %.17g]", d.orientation[0],
            d.orientation[1], d.orientation[2], d.orientation[3], d.orientation[4], d.orientation[5]);
    fprintf(fp, ", \"normal\": [%.17g, %.17g, %.17g], \"position\": [%.17g, %.17g, %.17g]",
            d.normal[0], d.normal[1], d.normal[2], d.position[0], d.position[1], d.position[2]);
    double lv[3];
    if (d.hounsfield && levels_of(s, lv))
        fprintf(fp, ", \"levels\": {\"bone\": %.17g, \"skin\": %.17g, \"otsu\": %.17g, "
                    "\"extract\": \"bone\"}",
                lv[ISOMEND_IO_LEVEL_BONE], lv[ISOMEND_IO_LEVEL_SKIN], lv[ISOMEND_IO_LEVEL_OTSU]);
    else
        fprintf(fp, ", \"levels\": null");
    fprintf(fp, ", \"files\": %lld, \"multiframe\": %s, \"non_image\": %lld, \"non_dicom\": %lld, "
                "\"other_series\": %lld, \"axes\": \"%s\", \"series\": ",
            (long long)d.files, d.multiframe ? "true" : "false", (long long)d.non_image,
            (long long)d.non_dicom, (long long)d.other_series,
            d.axes == ISOMEND_IO_AXES_GRID ? "grid" : "patient");
    cli_json_series(fp, s);
    fprintf(fp, "}");
#else
    (void)s;
    fprintf(fp, "null");
#endif
}

/* ------------------------------------------------------------------ NIfTI */

#ifdef ISOMEND_HAVE_IO
static int nifti_of(const cli_source *s, isomend_io_nifti *n)
{
    memset(n, 0, sizeof *n);
    n->size = sizeof *n;
    return s->io && strcmp(s->kind, "nifti") == 0 &&
           cli_io.nifti_info((const isomend_io_source *)s->io, n) == ISOMEND_IO_OK;
}

static const char *nifti_axes_name(int axes)
{
    return axes == ISOMEND_IO_AXES_GRID ? "grid" : axes == ISOMEND_IO_AXES_RAS ? "ras" : "patient";
}
#endif

void cli_print_nifti(FILE *fp, const cli_source *s)
{
#ifdef ISOMEND_HAVE_IO
    isomend_io_nifti n;
    if (!nifti_of(s, &n)) return;
    if (n.version)
        fprintf(fp, "  nifti:       NIfTI-%d%s%s, datatype %s\n", n.version,
                n.two_files ? " (.hdr/.img pair)" : "", n.gzip ? ", gzip" : "", n.datatype);
    else
        fprintf(fp, "  nifti:       ANALYZE 7.5 (.hdr/.img pair)%s, datatype %s\n",
                n.gzip ? ", gzip" : "", n.datatype);
    if (n.scaled)
        fprintf(fp, "  values:      scaled: scl_slope %g, scl_inter %g\n", n.scl_slope, n.scl_inter);
    fprintf(fp, "  transform:   %s (sform_code %d, qform_code %d), (i, j, k) -> RAS mm:\n",
            n.transform, n.sform_code, n.qform_code);
    for (int r = 0; r < 3; r++)
        fprintf(fp, "               %12.6g %12.6g %12.6g %12.6g\n", n.file_affine[4 * r],
                n.file_affine[4 * r + 1], n.file_affine[4 * r + 2], n.file_affine[4 * r + 3]);
    if (n.axes == ISOMEND_IO_AXES_GRID)
        fprintf(fp, "  axes:        grid (--grid-axes): x = i, y = j, z = k, not mapped to the world\n");
    else if (n.axes == ISOMEND_IO_AXES_RAS)
        fprintf(fp, "  axes:        RAS mm (--ras): x right, y anterior, z superior, as FSL/FreeSurfer\n");
    else
        fprintf(fp, "  axes:        patient (LPS mm, as DICOM): x to the patient's left, y posterior, "
                    "z head (--ras for RAS)\n");
#else
    (void)fp;
    (void)s;
#endif
}

void cli_json_nifti(FILE *fp, const cli_source *s)
{
#ifdef ISOMEND_HAVE_IO
    isomend_io_nifti n;
    if (!nifti_of(s, &n)) {
        fprintf(fp, "null");
        return;
    }
    fprintf(fp, "{\"version\": %d, \"two_files\": %s, \"gzip\": %s", n.version,
            n.two_files ? "true" : "false", n.gzip ? "true" : "false");
    json_text_member(fp, 0, "header_path", n.header_path);
    json_text_member(fp, 0, "image_path", n.image_path);
    json_text_member(fp, 0, "datatype", n.datatype);
    fprintf(fp, ", \"scaled\": %s, \"scl_slope\": %.17g, \"scl_inter\": %.17g, \"sform_code\": %d, "
                "\"qform_code\": %d",
            n.scaled ? "true" : "false", n.scl_slope, n.scl_inter, n.sform_code, n.qform_code);
    json_text_member(fp, 0, "transform", n.transform);
    fprintf(fp, ", \"file_affine\": ");
    cli_json_doubles(fp, n.file_affine, 12);
    json_text_member(fp, 0, "axes", nifti_axes_name(n.axes));
    fputc('}', fp);
#else
    (void)s;
    fprintf(fp, "null");
#endif
}
