#!/usr/bin/env python3
"""Reading a CT series: isomend's DICOM reader (GDCM, worker threads) beside
peers on the same samples, as ratios.

The series is 512 x 512 x SLICES int16 CT (12-bit stored + intercept -1024,
the CT phantom of tests/io/gen_dicom.py scaled up), written once into CACHE
by pydicom as uncompressed explicit VR files (and as RLE Lossless, and as a
TIFF stack of the same HU values).  Each reader runs ROUNDS times, the best
time is kept (a shared machine: the minimum is the least disturbed):

  isomend dicom tN   the read time `isomend extract --json` reports, N reader threads
  isomend rle tN     the same series RLE-compressed
  isomend tiff tN    the same volume as a TIFF stack (OpenImageIO)
  pydicom            pydicom.dcmread + pixel_array + rescale + sort, one thread
                     (what a Python script would do)

Usage: bench_dicom.py ISOMEND_CLI [--slices 300] [--rounds 3] [--cache DIR]
"""
import argparse
import json
import os
import subprocess
import sys
import time

import numpy as np

HERE = os.path.dirname(os.path.abspath(__file__))


def write_series(cache, slices, rle):
    import pydicom
    from pydicom.dataset import Dataset, FileMetaDataset
    from pydicom.uid import ExplicitVRLittleEndian, RLELossless, generate_uid
    out = os.path.join(cache, "ct_rle" if rle else "ct")
    if os.path.isdir(out) and len(os.listdir(out)) == slices:
        return out
    os.makedirs(out, exist_ok=True)
    z, y, x = np.ogrid[-1:1:slices * 1j, -1:1:512j, -1:1:512j]
    series, study = generate_uid(), generate_uid()
    for k in range(slices):
        r = np.sqrt((x / 0.8) ** 2 + (y / 0.75) ** 2 + (z[k] / 0.85) ** 2)
        hu = np.where(r < 1, 40, -1000) + np.where((r < 0.85) & (r >= 0.72), 860, 0)
        stored = (hu + 1024).astype(np.uint16)
        ds = Dataset()
        ds.SOPClassUID, ds.SOPInstanceUID = "1.2.840.10008.5.1.4.1.1.2", generate_uid()
        ds.SeriesInstanceUID, ds.StudyInstanceUID, ds.Modality = series, study, "CT"
        ds.ImagePositionPatient = [-128, -128, 0.625 * k]
        ds.ImageOrientationPatient = [1, 0, 0, 0, 1, 0]
        ds.PixelSpacing = [0.5, 0.5]
        ds.RescaleIntercept, ds.RescaleSlope = "-1024", "1"
        ds.SamplesPerPixel, ds.PhotometricInterpretation = 1, "MONOCHROME2"
        ds.Rows = ds.Columns = 512
        ds.BitsAllocated, ds.BitsStored, ds.HighBit, ds.PixelRepresentation = 16, 12, 11, 0
        ds.PixelData = stored.tobytes()
        meta = FileMetaDataset()
        meta.MediaStorageSOPClassUID, meta.MediaStorageSOPInstanceUID = ds.SOPClassUID, ds.SOPInstanceUID
        meta.TransferSyntaxUID = ExplicitVRLittleEndian
        ds.file_meta, ds.is_little_endian, ds.is_implicit_VR = meta, True, False
        if rle:
            ds.compress(RLELossless)
        ds.preamble = b"\0" * 128
        pydicom.dcmwrite(os.path.join(out, "%08d" % ((k * 7919) % 100000007)), ds, write_like_original=False)
    return out


def write_tiff(cache, dicom_dir, slices):
    import pydicom
    import tifffile
    out = os.path.join(cache, "ct_tiff")
    if os.path.isdir(out) and len(os.listdir(out)) == slices:
        return out
    os.makedirs(out, exist_ok=True)
    dss = sorted((pydicom.dcmread(os.path.join(dicom_dir, f)) for f in os.listdir(dicom_dir)),
                 key=lambda d: float(d.ImagePositionPatient[2]))
    for k, ds in enumerate(dss):
        tifffile.imwrite(os.path.join(out, "s_%04d.tif" % k), (ds.pixel_array.astype(np.int16) - 1024))
    return out


def isomend_read(cli, source, threads, cache):
    """The read time `isomend extract` reports (timings_ms.read) with N reader threads."""
    out = os.path.join(cache, "bench.ply")
    r = subprocess.run([cli, "extract", source, "--iso", "300", "--threads", str(threads), "-o", out,
                        "--json", "-", "--quiet"], capture_output=True, text=True)
    if r.returncode:
        sys.exit("isomend failed: %s" % r.stderr)
    return json.loads(r.stdout)["timings_ms"]["read"] / 1e3


def pydicom_read(folder):
    import pydicom
    t0 = time.perf_counter()
    dss = [pydicom.dcmread(os.path.join(folder, f)) for f in os.listdir(folder)]
    dss.sort(key=lambda d: float(d.ImagePositionPatient[2]))
    vol = np.stack([d.pixel_array.astype(np.int16) * int(d.RescaleSlope) + int(d.RescaleIntercept)
                    for d in dss])
    assert vol.shape[1:] == (512, 512)
    return time.perf_counter() - t0


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("cli")
    ap.add_argument("--slices", type=int, default=300)
    ap.add_argument("--rounds", type=int, default=3)
    ap.add_argument("--cache", default=os.path.expanduser("~/.cache/isomend/bench_dicom"))
    a = ap.parse_args()
    os.makedirs(a.cache, exist_ok=True)
    plain = write_series(a.cache, a.slices, False)
    rle = write_series(a.cache, a.slices, True)
    tiff = write_tiff(a.cache, plain, a.slices)
    rows = {}
    for threads in (1, 2):
        for label, src in (("isomend dicom", plain), ("isomend rle", rle), ("isomend tiff", tiff)):
            rows["%s t%d" % (label, threads)] = min(isomend_read(a.cli, src, threads, a.cache)
                                                   for _ in range(a.rounds))
    rows["pydicom t1"] = min(pydicom_read(plain) for _ in range(a.rounds))
    base = rows["isomend dicom t1"]
    mb = 512 * 512 * a.slices * 2 / 2 ** 20
    print("512 x 512 x %d int16 CT (%.0f MiB), best of %d, %d cores:" % (a.slices, mb, a.rounds, os.cpu_count()))
    for label, t in rows.items():
        print("  %-18s %7.3f s  %6.0f MiB/s  %5.2fx isomend dicom t1" % (label, t, mb / t, t / base))


if __name__ == "__main__":
    main()
