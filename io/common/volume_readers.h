/*
 * volume_readers.h - raw and NRRD volume readers of isomend (io/common)
 *
 * Part of the static library `isomend_fileio` (C11, zlib), used by the
 * `isomend` command line and by the slice-stack importer `isomend_io`, so
 * that every tool opens raw and NRRD files through the same code and gives
 * the same messages.
 *
 * Two steps, so that a caller can check sizes and memory before allocating:
 *
 *   1. probe: isomend_fileio_probe_raw() (headerless file described by the
 *      caller) or isomend_fileio_probe_nrrd() (.nrrd with attached data or
 *      .nhdr with a detached "data file") fills an isomend_fileio_info: the
 *      dimensions, sample type, byte order, spacing, origin, and where the
 *      samples are (file, offset, encoding).  For raw encodings the probe
 *      checks that the data file holds *exactly* the bytes the dimensions
 *      need; for gzip it checks that the compressed size can possibly hold
 *      them (deflate never exceeds ~1032:1).  No sample is read.
 *   2. read: isomend_fileio_read() into a caller buffer (whole volume or a
 *      range of z slices), or isomend_fileio_load() into a malloc'ed buffer.
 *      Samples arrive contiguous, x fastest, in the machine's byte order.
 *      A gzip stream that ends early, holds more data than the header says
 *      or is corrupt is an error, never silently zero-filled.
 *
 * NRRD support (http://teem.sourceforge.net/nrrd/format.html, NRRD0001 to
 * NRRD0005): "dimension: 3"; types u8 i8 u16 i16 i32 f32 f64 under all their
 * NRRD spellings ("uchar", "unsigned short", "int16_t", ...); encodings raw
 * and gzip (also "gz"); "endian"; "sizes"; "spacings" or "space directions"
 * (spacing = the length of each axis vector; off-axis vectors are reported
 * in info.oblique, since isomend's grids are axis aligned); "space origin";
 * "byte skip" (-1 = data is at the end of a raw file); "line skip";
 * "data file"/"datafile" relative to the header's folder.  Unsupported
 * types, encodings, dimensions and multi-file data are refused by name.
 *
 * Errors: every function returns an isomend_fileio_status and, when `msg`
 * is not NULL, writes one line naming the file and the reason into
 * msg[0..msg_size) (ISOMEND_FILEIO_MSG_SIZE bytes are always enough), e.g.
 *   "vol.raw: file has 999 bytes, 10x10x10 u8 needs 1000"
 *   "head.nrrd: line 4: unknown type 'uint64' (supported: u8 i8 u16 i16 i32 f32 f64)"
 *
 * Thread safety: no global state; different calls may run in parallel.
 */
#ifndef ISOMEND_VOLUME_READERS_H
#define ISOMEND_VOLUME_READERS_H

#include <stddef.h>
#include <stdint.h>

#include "fileio_status.h"
#include "isomend.h"

#ifdef __cplusplus
extern "C" {
#endif

typedef enum isomend_fileio_encoding {
    ISOMEND_FILEIO_ENC_RAW = 0,
    ISOMEND_FILEIO_ENC_GZIP = 1
} isomend_fileio_encoding;

/* What a probe found.  Plain data: may be copied. */
typedef struct isomend_fileio_info {
    int64_t dims[3];           /* x (fastest), y, z; all >= 1                   */
    isomend_type type;
    int big_endian;            /* byte order of the stored samples              */
    double spacing[3];         /* > 0; 1 where unknown                          */
    double origin[3];          /* world position of sample (0,0,0); 0 if unknown */
    int spacing_known;         /* 1 if the header gave spacings/space directions */
    int origin_known;          /* 1 if the header gave a space origin            */
    int oblique;               /* 1 if "space directions" are not axis aligned   */
    int is_nrrd;               /* 0 raw, 1 NRRD                                  */
    isomend_fileio_encoding encoding;
    char path[ISOMEND_FILEIO_PATH_MAX];      /* the file probed                 */
    char data_path[ISOMEND_FILEIO_PATH_MAX]; /* where the samples are           */
    uint64_t data_offset;      /* bytes to skip in data_path (raw: exact; gzip:  */
                               /* where the compressed stream starts)           */
    uint64_t line_skip;        /* NRRD "line skip", applied before data_offset   */
    uint64_t data_file_bytes;  /* size of data_path                             */
    int axis_negative[3];      /* 1 if "space directions" point axis a along -a  */
                               /* (e.g. NIfTI-derived RAS data): world position  */
                               /* decreases with the index; see describe()       */
} isomend_fileio_info;

/* Bytes of the decoded volume (dims product * sample size); 0 on overflow. */
uint64_t isomend_fileio_volume_bytes(const isomend_fileio_info *info);

/*
 * Describes a headerless file: `dims` all >= 1, `type` valid, `header_bytes`
 * skipped at the start.  Fails with ISOMEND_FILEIO_ERR_SIZE unless the file
 * holds exactly header_bytes + volume bytes.
 */
isomend_fileio_status isomend_fileio_probe_raw(const char *path, const int64_t dims[3],
                                               isomend_type type, int big_endian,
                                               uint64_t header_bytes, isomend_fileio_info *info,
                                               char *msg, size_t msg_size);

/* Parses a NRRD header (.nrrd attached or .nhdr detached) and checks sizes. */
isomend_fileio_status isomend_fileio_probe_nrrd(const char *path, isomend_fileio_info *info,
                                                char *msg, size_t msg_size);

/* 1 if the path ends in .nrrd or .nhdr (any case), else 0. */
int isomend_fileio_is_nrrd_path(const char *path);

/*
 * Progress for reads: fraction in [0, 1], called from the calling thread
 * every few MiB.  Return non-zero to cancel (ISOMEND_FILEIO_ERR_CANCELLED).
 */
typedef int (*isomend_fileio_progress_fn)(void *user, double fraction);

/*
 * Reads z slices [first_slice, first_slice + slice_count) into `buffer`
 * (at least slice_count * nx * ny * sample size bytes; `buffer_size` says
 * how many there are).  Contiguous, x fastest, machine byte order.  Raw
 * data is read with a seek; gzip data is decompressed from the start and
 * the slices before `first_slice` are discarded.  `progress` may be NULL.
 */
isomend_fileio_status isomend_fileio_read(const isomend_fileio_info *info, int64_t first_slice,
                                          int64_t slice_count, void *buffer, size_t buffer_size,
                                          isomend_fileio_progress_fn progress, void *progress_user,
                                          char *msg, size_t msg_size);

/*
 * Slice by slice, for volumes larger than memory: the slices in the order
 * and orientation isomend_fileio_describe() presents the volume (z = 0
 * first; an axis with axis_negative reversed), each contiguous, x fastest,
 * machine byte order, isomend_fileio_slices_bytes() bytes.  Memory: the
 * caller's slice buffer plus ~330 KiB (the decompressor's), whatever nz.
 * Raw data is read where it lies (a reversed z axis reads the file from its
 * last slice back); gzip data is inflated forwards once, and a gzip volume
 * with a reversed z axis is refused (ISOMEND_FILEIO_ERR_UNSUPPORTED) since
 * its first slice is the stream's last.  The last slice checks that a gzip
 * stream ends exactly there, as isomend_fileio_read() does.  `info` is
 * copied.  One thread at a time per reader.
 */
typedef struct isomend_fileio_slices isomend_fileio_slices;

isomend_fileio_status isomend_fileio_slices_open(const isomend_fileio_info *info,
                                                 isomend_fileio_slices **out, char *msg,
                                                 size_t msg_size);
uint64_t isomend_fileio_slices_bytes(const isomend_fileio_slices *s);
/* The next slice into `buffer` (at least isomend_fileio_slices_bytes() bytes). */
isomend_fileio_status isomend_fileio_slices_next(isomend_fileio_slices *s, void *buffer,
                                                 size_t buffer_size, char *msg, size_t msg_size);
/* The next call delivers slice `slice` (0..dims[2]).  Raw data seeks;
 * gzip data skips forwards by inflating (backwards: from the start again). */
isomend_fileio_status isomend_fileio_slices_seek(isomend_fileio_slices *s, int64_t slice,
                                                 char *msg, size_t msg_size);
/* Accepts NULL. */
void isomend_fileio_slices_close(isomend_fileio_slices *s);

/*
 * Reads the whole volume into a new malloc'ed buffer (*out_data; release it
 * with free()).  On failure *out_data is NULL.
 */
isomend_fileio_status isomend_fileio_load(const isomend_fileio_info *info, void **out_data,
                                          isomend_fileio_progress_fn progress,
                                          void *progress_user, char *msg, size_t msg_size);

/*
 * Fills an isomend_volume describing `data` read for `info`: contiguous
 * strides, spacing and origin from the header.  For an axis with
 * axis_negative set, the volume is described in reverse along that axis
 * (data pointer at the last sample, negative stride, origin moved to the
 * last sample's world position), so the mesh lands at the samples' true
 * world positions, unmirrored.
 */
void isomend_fileio_describe(const isomend_fileio_info *info, const void *data,
                             isomend_volume *vol);

/*
 * Otsu's threshold (1979) on a histogram of `bins` equal bins spanning
 * [min, max]: the split that maximises the between-class variance.  When
 * empty bins between two classes give the same variance, the level goes to
 * the middle of that gap (not its first bin).  With `integer` non-zero the
 * level is moved to floor(t) + 0.5, so that no sample equals it.  Returns
 * min when max <= min.  The command line and the slice-stack importer both
 * suggest iso levels with it, so a volume gets the same suggestion as raw,
 * NRRD or image stack.
 */
double isomend_fileio_otsu(const uint64_t *hist, int bins, double min, double max, int integer);

/*
 * Writes a NRRD0004 file with attached data (gzip level 6 when `gzip` is
 * non-zero, else raw), little endian, "spacings" and "space origin" from
 * `vol`.  The volume may have any strides.  The file is written to a
 * temporary file in the same folder and renamed at the end: on failure no
 * file (and no temporary) is left.
 */
isomend_fileio_status isomend_fileio_write_nrrd(const char *path, const isomend_volume *vol,
                                                int gzip, char *msg, size_t msg_size);

#ifdef __cplusplus
}
#endif

#endif /* ISOMEND_VOLUME_READERS_H */
