#!/usr/bin/env python3
"""Writes the DICOM test series of tests/io into OUTDIR, with pydicom (Debian's
python3-pydicom, an implementation independent of GDCM), and a manifest.

The volumes are the project's test volumes: samples/anatomical.nrrd (a T1 MRI
head, as MRI-like uint16) and a CT-like phantom made here (a head: air, skin,
soft tissue, a skull shell of bone, in HU).  For every good case the volume
isomend_io must deliver (sorted along the normal, rescaled, inverted for
MONOCHROME1) is written next to it as little-endian raw, x fastest, with its
expected geometry; the files themselves are written in a shuffled order under
shuffled names, and the positions are computed from the geometry, so sorting,
spacing and orientation are all checked against what was meant.

manifest.tsv, one case per line, tab-separated:
  ok   NAME TYPE NX NY NZ EXPECTED.raw SX SY SZ OX OY OZ A0..A11 SERIES AXES
       ORIGINS WARN TILT LONG SOURCE...
  err  NAME STATUS MESSAGE-SUBSTRING SERIES SOURCE...
O = the origin isomend_io_load() describes (the series' own frame), A = the
world transform (3x4 row-major); SERIES "-" for none; AXES 0 patient, 1 grid;
ORIGINS "-" for a uniform grid, else a file of the slice origins
isomend_io_slice_origins() must give (the series' own frame, one slice a
line, x y z); WARN 1 when isomend_io_geometry_info() must give a warning,
else 0; TILT its tilt in degrees, LONG its count of gaps over 1.5x the
median; STATUS an isomend_io_status number (of isomend_io_open, or of the
load when the open succeeds).  SOURCE paths are relative to OUTDIR.
The geometry is computed here from the values as written (DS text read
back), by the rule of isomend_io.h ("Slices where they are"): uniform when
every slice origin lies within 1e-4 of the smaller pixel spacing of the
evenly spaced line through the first and last; a warning when a gap along n
differs from the median by more than 1% or exceeds 1.5x it.
cases.json: the same cases for the Python tests, with the geometry of each
("slice_origins": null or [[x, y, z], ...], "warning", "tilt_degrees").

Usage: gen_dicom.py OUTDIR SAMPLES_DIR
"""
import json
import os
import re
import shutil
import subprocess
import sys

import numpy as np
import pydicom

sys.dont_write_bytecode = True  # no __pycache__ in the source tree
sys.path.insert(0, os.path.join(os.path.dirname(os.path.abspath(__file__)), "..", "common"))
from clitest import read_nrrd  # noqa: E402
from pydicom.dataset import Dataset, FileMetaDataset
from pydicom.sequence import Sequence
from pydicom.uid import (ExplicitVRLittleEndian, ImplicitVRLittleEndian, RLELossless,
                         generate_uid)

OUT = os.path.abspath(sys.argv[1])
SAMPLES = os.path.abspath(sys.argv[2])
shutil.rmtree(OUT, ignore_errors=True)
os.makedirs(OUT)
RNG = np.random.default_rng(20261203)
LINES = []
CASES = {}

# isomend_io_status values (isomend_io.h)
NOT_FOUND, UNREADABLE, CORRUPT, MISMATCH, UNSUPPORTED, TOO_FEW, SERIES = 2, 3, 4, 5, 6, 7, 13
CT_IMAGE = "1.2.840.10008.5.1.4.1.1.2"
ENHANCED_CT = "1.2.840.10008.5.1.4.1.1.2.1"
MR_IMAGE = "1.2.840.10008.5.1.4.1.1.4"
BASIC_TEXT_SR = "1.2.840.10008.5.1.4.1.1.88.11"


def d(*parts):
    p = os.path.join(OUT, *parts)
    os.makedirs(p, exist_ok=True)
    return p


# ---------------------------------------------------------------- volumes

def ct_phantom(nx=40, ny=36, nz=30):
    """A head in HU, [z, y, x]: air -1000, skin/soft tissue 40, a bone shell
    of 700-1200 HU, brain 30, a little noise; asymmetric (a nose bump at +y)."""
    z, y, x = np.meshgrid(np.linspace(-1, 1, nz), np.linspace(-1, 1, ny), np.linspace(-1, 1, nx),
                          indexing="ij")
    r = np.sqrt((x / 0.8) ** 2 + (y / 0.75) ** 2 + (z / 0.85) ** 2)
    hu = np.full(r.shape, -1000.0)
    hu[r < 1.0] = 40.0
    hu[(r < 0.85) & (r >= 0.72)] = 900.0 + 300.0 * x[(r < 0.85) & (r >= 0.72)]
    hu[r < 0.72] = 30.0
    nose = (np.abs(x) < 0.15) & (y > 0.6) & (y < 0.9) & (np.abs(z) < 0.2)
    hu[nose] = 40.0
    hu += RNG.normal(0, 8, hu.shape)
    return np.clip(np.round(hu), -1024, 3071).astype(np.int16)


MRI = read_nrrd(os.path.join(SAMPLES, "anatomical.nrrd")).astype(np.int32)
MRI_U16 = (MRI - MRI.min()).astype(np.uint16)       # MRI-like uint16, [z, y, x]
CT = ct_phantom()                                   # HU, int16, [z, y, x]


# ---------------------------------------------------------------- geometry

def rotation(axis, degrees):
    a = np.asarray(axis, float) / np.linalg.norm(axis)
    t = np.radians(degrees)
    k = np.array([[0, -a[2], a[1]], [a[2], 0, -a[0]], [-a[1], a[0], 0]])
    return np.eye(3) + np.sin(t) * k + (1 - np.cos(t)) * k @ k


class Geometry:
    """row, col: direction cosines; spacing (sx, sy, sz); p0: position of slice 0."""

    def __init__(self, row=(1, 0, 0), col=(0, 1, 0), spacing=(0.7, 0.8, 1.25), p0=(-14.0, -12.5, 40.0)):
        self.row = np.asarray(row, float)
        self.col = np.asarray(col, float)
        self.n = np.cross(self.row, self.col)
        self.spacing = tuple(float(s) for s in spacing)
        self.p0 = np.asarray(p0, float)

    def position(self, k):
        return self.p0 + k * self.spacing[2] * self.n

    def R(self):
        return np.column_stack([self.row, self.col, self.n])

    def own_origin(self):
        return self.R().T @ self.p0

    def affine(self, axes=0):
        if axes == 1 or np.array_equal(self.R(), np.eye(3)):
            return np.hstack([np.eye(3), np.zeros((3, 1))])
        R = self.R()
        return np.hstack([R, (self.p0 - R @ self.own_origin())[:, None]])


def ds_text(v):
    """DS with up to 16 characters, as scanners write them."""
    s = "%.10g" % v
    return s if len(s) <= 16 else "%.8g" % v


# ---------------------------------------------------------------- writing

def base_dataset(sop_class, modality, series_uid, study_uid, frame_uid, number=1, description=""):
    ds = Dataset()
    ds.SOPClassUID = sop_class
    ds.SOPInstanceUID = generate_uid()
    ds.StudyInstanceUID = study_uid
    ds.SeriesInstanceUID = series_uid
    ds.FrameOfReferenceUID = frame_uid
    ds.Modality = modality
    ds.PatientName = "Phantom^Isomend"
    ds.PatientID = "ISOMEND-TEST"
    ds.SeriesNumber = number
    ds.SeriesDescription = description
    ds.StudyDate, ds.StudyTime, ds.StudyID = "20261203", "120000", "1"
    return ds


def finish(ds, path, syntax=ExplicitVRLittleEndian):
    meta = FileMetaDataset()
    meta.MediaStorageSOPClassUID = ds.SOPClassUID
    meta.MediaStorageSOPInstanceUID = ds.SOPInstanceUID
    meta.TransferSyntaxUID = ExplicitVRLittleEndian if syntax == RLELossless else syntax
    ds.file_meta = meta
    ds.is_little_endian = True
    ds.is_implicit_VR = syntax == ImplicitVRLittleEndian
    if syntax == RLELossless:
        ds.compress(RLELossless)
    ds.preamble = b"\0" * 128
    pydicom.dcmwrite(path, ds, write_like_original=False)


def set_pixels(ds, stored, signed, bits_stored):
    ds.SamplesPerPixel = 1
    ds.PhotometricInterpretation = getattr(ds, "PhotometricInterpretation", "MONOCHROME2")
    ds.Rows, ds.Columns = stored.shape[-2], stored.shape[-1]
    ds.BitsAllocated = stored.dtype.itemsize * 8
    ds.BitsStored = bits_stored
    ds.HighBit = bits_stored - 1
    ds.PixelRepresentation = 1 if signed else 0
    ds.PixelData = np.ascontiguousarray(stored).astype(stored.dtype.newbyteorder("<")).tobytes()


def write_series(folder, stored, geo, *, modality="CT", sop_class=CT_IMAGE, signed=False,
                 bits_stored=None, slope=None, intercept=None, syntax=ExplicitVRLittleEndian,
                 names="shuffled", number=1, description="", series_uid=None, photometric=None,
                 edit=None, positions=None):
    """stored: [z, y, x] as stored, slice k at geo.position(k) (or
    positions[k]).  Files are written in a shuffled order, Instance Numbers
    shuffled too.  Returns the paths in slice order."""
    series_uid = series_uid or generate_uid()
    study, frame = generate_uid(), generate_uid()
    nz = stored.shape[0]
    order = RNG.permutation(nz)
    instance = RNG.permutation(nz) + 1
    paths = [None] * nz
    for i, k in enumerate(order):
        ds = base_dataset(sop_class, modality, series_uid, study, frame, number, description)
        ds.InstanceNumber = int(instance[k])
        ds.ImagePositionPatient = [ds_text(v) for v in (geo.position(k) if positions is None else positions[k])]
        ds.ImageOrientationPatient = [ds_text(v) for v in list(geo.row) + list(geo.col)]
        ds.PixelSpacing = [ds_text(geo.spacing[1]), ds_text(geo.spacing[0])]  # row, column spacing
        ds.SliceThickness = ds_text(geo.spacing[2])
        if photometric:
            ds.PhotometricInterpretation = photometric
        if slope is not None:
            ds.RescaleSlope = ds_text(slope)
            ds.RescaleIntercept = ds_text(intercept)
            if modality == "CT":
                ds.RescaleType = "HU"
        set_pixels(ds, stored[k], signed, bits_stored or stored.dtype.itemsize * 8)
        if names == "shuffled":
            name = "%08x" % RNG.integers(0, 2 ** 32)          # no extension, random order
        elif names == "dcm":
            name = "IMG%04d.dcm" % (i + 1)
        else:
            name = names % (i + 1)
        if edit:
            edit(k, ds)
        p = os.path.join(folder, name)
        finish(ds, p, syntax)
        paths[k] = p
    return paths


def written(v):
    """A DS value as isomend reads it back."""
    return float(ds_text(v))


def slice_geometry(geo, positions):
    """The slices' geometry by the rule of isomend_io.h, from the values as
    written: (origins [n, 3] in the series' own frame, uniform, warning,
    tilt degrees, gaps over 1.5x the median, mean gap)."""
    row = np.array([written(v) for v in geo.row])
    col = np.array([written(v) for v in geo.col])
    r, c = row / np.sqrt(row @ row), col / np.sqrt(col @ col)
    n = np.cross(r, c)
    n /= np.sqrt(n @ n)
    P = np.array([[written(v) for v in p] for p in positions])
    o = np.column_stack([P @ r, P @ c, P @ n])
    assert np.all(np.diff(o[:, 2]) > 0), "positions must be written in slice order"
    k = np.arange(len(o))
    mean = (o[-1, 2] - o[0, 2]) / (len(o) - 1)
    even = o[0] + np.outer(k * mean, [0, 0, 1])
    offset = np.sqrt(((o - even) ** 2).sum(1)).max()
    gaps = np.diff(o[:, 2])
    median = np.sort(gaps)[len(gaps) // 2]
    long_gaps = int((gaps > 1.5 * median).sum())
    warning = bool((np.abs(gaps - median) > 0.01 * median).any() or long_gaps)
    d = o[-1] - o[0]
    tilt = float(np.degrees(np.arctan2(np.hypot(d[0], d[1]), d[2])))
    uniform = offset <= 1e-4 * min(geo.spacing[0], geo.spacing[1])
    return o, bool(uniform), warning, tilt, long_gaps, float(mean)


def expected(name, vol, geo, axes=0, series="-", sources=(), tname=None, spacing=None, positions=None):
    """Records a good case: vol [z, y, x] in the delivered dtype; the slices
    at geo.position(k), or positions[k] (written in slice order)."""
    nz, ny, nx = vol.shape
    p = os.path.join(OUT, name + ".expected.raw")
    np.ascontiguousarray(vol).astype(vol.dtype.newbyteorder("<")).tofile(p)
    tname = tname or {np.dtype(np.uint8): "u8", np.dtype(np.int8): "i8", np.dtype(np.uint16): "u16",
                      np.dtype(np.int16): "i16", np.dtype(np.int32): "i32",
                      np.dtype(np.float32): "f32", np.dtype(np.float64): "f64"}[vol.dtype]
    sp = spacing or geo.spacing
    origin = geo.own_origin()
    if positions is None:
        positions = [geo.position(k) for k in range(nz)]
    table, uniform, warning, tilt, long_gaps, mean = slice_geometry(geo, positions)
    if not uniform:  # the series' own values: slice 0's origin, the mean gap
        origin, sp = table[0], (sp[0], sp[1], mean)
        origins_file = name + ".origins.txt"
        np.savetxt(os.path.join(OUT, origins_file), table, fmt="%.17g")
    A = geo.affine(axes)
    rel = [os.path.relpath(s, OUT) for s in sources]
    LINES.append("\t".join(["ok", name, tname, str(nx), str(ny), str(nz), os.path.basename(p)] +
                           ["%.17g" % v for v in sp] + ["%.17g" % v for v in origin] +
                           ["%.17g" % v for v in A.reshape(-1)] + [series, str(axes)] +
                           ["-" if uniform else origins_file, str(int(warning)), "%.17g" % tilt,
                            str(long_gaps)] + rel))
    CASES[name] = {"ok": True, "type": tname, "dims": [nx, ny, nz], "expected": p, "spacing": list(sp),
                   "origin": list(origin), "affine": A.tolist(), "p0": geo.p0.tolist(),
                   "series": None if series == "-" else series, "axes": axes,
                   "slice_origins": None if uniform else table.tolist(), "warning": warning,
                   "tilt_degrees": tilt, "long_gaps": long_gaps,
                   "sources": [os.path.join(OUT, r) for r in rel]}
    return table, uniform, warning, tilt, long_gaps


def error(name, status, substring, sources, series="-"):
    rel = [os.path.relpath(s, OUT) for s in sources]
    LINES.append("\t".join(["err", name, str(status), substring, series] + rel))
    CASES[name] = {"ok": False, "status": status, "substring": substring,
                   "series": None if series == "-" else series,
                   "sources": [os.path.join(OUT, r) for r in rel]}


def text_sr(folder, series_uid=None):
    """A Basic Text SR: a DICOM object without pixel data (to be ignored)."""
    ds = base_dataset(BASIC_TEXT_SR, "SR", series_uid or generate_uid(), generate_uid(), generate_uid(), 99,
                      "report")
    ds.ValueType = "CONTAINER"
    p = os.path.join(folder, "report")
    finish(ds, p)
    return p


# ---------------------------------------------------------------- good series

# CT, 12-bit unsigned stored = HU + 1024, intercept -1024: HU as i16; shuffled
# names without extension, a report and a non-DICOM file in the folder
geo_ct = Geometry(spacing=(0.7, 0.8, 1.25), p0=(-14.0, -12.5, 40.0))
f = d("ct")
write_series(f, (CT.astype(np.int32) + 1024).astype(np.uint16), geo_ct, bits_stored=12, slope=1, intercept=-1024,
             description="CT head phantom")
text_sr(f)
open(os.path.join(f, "README.txt"), "w").write("exported by a test\n")
expected("ct_folder", CT, geo_ct, sources=[f])

# CT stored signed 16 bits with intercept -1024: the header allows
# [-32768, 32767] - 1024, so i32 (no clipping)
geo_ct2 = Geometry(spacing=(0.5, 0.5, 2.0), p0=(10.0, 20.0, -30.0))
f = d("ct_signed")
write_series(f, (CT.astype(np.int32) + 1024).astype(np.int16), geo_ct2, signed=True, slope=1, intercept=-1024,
             names="dcm")
expected("ct_signed", CT.astype(np.int32), geo_ct2, sources=[f])

# MRI-like uint16, no rescale, implicit VR, .dcm names, 1 mm x 2 mm pixels
geo_mr = Geometry(spacing=(1.0, 2.0, 1.5), p0=(0.0, 0.0, 0.0))
f = d("mr")
write_series(f, MRI_U16, geo_mr, modality="MR", sop_class=MR_IMAGE, syntax=ImplicitVRLittleEndian, names="dcm",
             description="T1")
expected("mr_u16", MRI_U16, geo_mr, sources=[f])

# RLE Lossless (a compressed transfer syntax GDCM decodes)
f = d("ct_rle")
write_series(f, (CT.astype(np.int32) + 1024).astype(np.uint16), geo_ct, bits_stored=12, slope=1, intercept=-1024,
             syntax=RLELossless)
expected("ct_rle", CT, geo_ct, sources=[f])

# Oblique: rows and columns turned 30 degrees about (1, 2, 0.5); patient and grid axes
R = rotation((1, 2, 0.5), 30)
geo_ob = Geometry(row=R[:, 0], col=R[:, 1], spacing=(0.7, 0.8, 1.25), p0=(5.0, -7.0, 12.0))
f = d("ct_oblique")
write_series(f, (CT.astype(np.int32) + 1024).astype(np.uint16), geo_ob, bits_stored=12, slope=1, intercept=-1024)
# the positions are written with 10 digits: the expected frame is the files' own
expected("ct_oblique", CT, geo_ob, sources=[f])
expected("ct_oblique_grid", CT, geo_ob, axes=1, sources=[f])

# Feet first, mirrored rows: row (-1,0,0), column (0,1,0), so the normal is -z
# and the slices go down in z; still a rotation (det +1)
geo_ff = Geometry(row=(-1, 0, 0), col=(0, 1, 0), spacing=(0.7, 0.8, 1.25), p0=(14.0, -12.5, 40.0))
f = d("ct_feet_first")
write_series(f, (CT.astype(np.int32) + 1024).astype(np.uint16), geo_ff, bits_stored=12, slope=1, intercept=-1024)
expected("ct_feet_first", CT, geo_ff, sources=[f])

# Coronal: row (1,0,0), column (0,0,-1)
geo_cor = Geometry(row=(1, 0, 0), col=(0, 0, -1), spacing=(0.7, 0.8, 1.25), p0=(-14.0, 10.0, 30.0))
f = d("mr_coronal")
write_series(f, MRI_U16, geo_cor, modality="MR", sop_class=MR_IMAGE)
expected("mr_coronal", MRI_U16, geo_cor, sources=[f])

# MONOCHROME1, 12 bits: delivered inverted, 4095 - s
f = d("mono1")
mono = MRI_U16[:, :, :].astype(np.int32)
mono = (mono * 4095 // max(1, mono.max())).astype(np.uint16)
write_series(f, mono, geo_mr, modality="MR", sop_class=MR_IMAGE, bits_stored=12, photometric="MONOCHROME1")
expected("mono1", (4095 - mono.astype(np.int32)).astype(np.uint16), geo_mr, sources=[f])

# A non-integer slope: f32
f = d("mr_slope")
write_series(f, MRI_U16, geo_mr, modality="MR", sop_class=MR_IMAGE, slope=2.5, intercept=-10.25)
expected("mr_slope", (MRI_U16.astype(np.float64) * 2.5 - 10.25).astype(np.float32), geo_mr, sources=[f])

# Two series in one folder: an error naming both without a choice; by position and by UID
f = d("two_series")
uid_mr = generate_uid()
write_series(f, MRI_U16, geo_mr, modality="MR", sop_class=MR_IMAGE, number=7, series_uid=uid_mr, description="T1")
write_series(f, (CT.astype(np.int32) + 1024).astype(np.uint16), geo_ct, bits_stored=12, slope=1, intercept=-1024,
             number=3, description="CT head phantom")
error("two_series", SERIES, "2 DICOM series", [f])
expected("two_series_n2", MRI_U16, geo_mr, series="2", sources=[f])
expected("two_series_uid", MRI_U16, geo_mr, series=uid_mr, sources=[f])
error("two_series_n3", SERIES, "no series 3", [f], series="3")

# A list of files (in any order) and the single-frame rule
f = d("ct_list")
paths = write_series(f, (CT.astype(np.int32) + 1024).astype(np.uint16), geo_ct, bits_stored=12, slope=1,
                     intercept=-1024, names="slice%03d.dcm")
listed = list(paths)
RNG.shuffle(listed)
expected("ct_list", CT, geo_ct, sources=listed)
expected("ct_glob", CT, geo_ct, sources=[os.path.join(f, "slice*.dcm")])
error("single_image", TOO_FEW, "a single DICOM image", [paths[0]])

# Enhanced CT: one multi-frame file, frames stored in a shuffled order, per-frame positions
f = d("ct_multiframe")
order = RNG.permutation(CT.shape[0])
ds = base_dataset(ENHANCED_CT, "CT", generate_uid(), generate_uid(), generate_uid(), 5, "enhanced")
ds.NumberOfFrames = CT.shape[0]
shared = Dataset()
pm = Dataset()
pm.PixelSpacing = [ds_text(geo_ct.spacing[1]), ds_text(geo_ct.spacing[0])]
pm.SliceThickness = ds_text(geo_ct.spacing[2])
po = Dataset()
po.ImageOrientationPatient = [ds_text(v) for v in list(geo_ct.row) + list(geo_ct.col)]
pv = Dataset()
pv.RescaleIntercept = "-1024"
pv.RescaleSlope = "1"
pv.RescaleType = "HU"
shared.PixelMeasuresSequence = Sequence([pm])
shared.PlaneOrientationSequence = Sequence([po])
shared.PixelValueTransformationSequence = Sequence([pv])
ds.SharedFunctionalGroupsSequence = Sequence([shared])
per = []
for k in order:
    item = Dataset()
    pp = Dataset()
    pp.ImagePositionPatient = [ds_text(v) for v in geo_ct.position(k)]
    item.PlanePositionSequence = Sequence([pp])
    per.append(item)
ds.PerFrameFunctionalGroupsSequence = Sequence(per)
set_pixels(ds, (CT[order].astype(np.int32) + 1024).astype(np.uint16), False, 12)
finish(ds, os.path.join(f, "enhanced.dcm"))
expected("ct_multiframe", CT, geo_ct, sources=[os.path.join(f, "enhanced.dcm")])

# DICOMDIR (pydicom's FileSet writes the folder tree and the DICOMDIR)
try:
    from pydicom.fileset import FileSet
    src = d("_dicomdir_src")
    paths = write_series(src, (CT.astype(np.int32) + 1024).astype(np.uint16), geo_ct, bits_stored=12, slope=1,
                         intercept=-1024, names="x%03d.dcm")
    fs = FileSet()
    for p in paths:
        fs.add(p)
    out = d("dicomdir")
    fs.write(out)
    shutil.rmtree(src)
    expected("dicomdir", CT, geo_ct, sources=[os.path.join(out, "DICOMDIR")])
    expected("dicomdir_folder", CT, geo_ct, sources=[out])
except ImportError:  # pydicom < 2.2 has no FileSet: the CI's Debian 12 has 2.3
    raise

# An export's root: no files at the top, the series two folders down
f = d("export_root", "PATIENT", "STUDY1")
write_series(f, MRI_U16, geo_mr, modality="MR", sop_class=MR_IMAGE)
expected("export_root", MRI_U16, geo_mr, sources=[os.path.join(OUT, "export_root")])

# JPEG lossless, JPEG-LS and JPEG 2000 (lossless), encoded by gdcmconv (libgdcm-tools)
GDCMCONV = shutil.which("gdcmconv")
if not GDCMCONV:
    sys.exit("gen_dicom: gdcmconv not found: install libgdcm-tools (scripts/deps.sh test does)")
if GDCMCONV:
    for tag, flags in (("jpeg", ["--jpeg"]), ("j2k", ["--j2k"]),
                       ("jpegls", ["--jpegls"])):
        src = os.path.join(OUT, "ct_rle")
        f = d("ct_" + tag)
        for n in sorted(os.listdir(src)):
            subprocess.run([GDCMCONV] + flags + [os.path.join(src, n), os.path.join(f, n)], check=True)
        expected("ct_" + tag, CT, geo_ct, sources=[f])

# ---------------------------------------------------------------- slices where they are
# Series that are not evenly spaced on one line are meshed at their slices'
# true positions (isomend_io.h, "Slices where they are"): each case asserts
# here that it really is what it is named for, by the rule the importer uses.
CT_STORED = (CT.astype(np.int32) + 1024).astype(np.uint16)


def placed(name, stored, delivered, geo, positions, **kw):
    f = d(name)
    write_series(f, stored, geo, positions=positions, names="IM%04d", **kw)
    return expected(name, delivered, geo, sources=[f], positions=positions)


# "rounded": an oblique MR whose Image Position (Patient) values are rounded
# to 0.1 mm, as GE scanners write them: ~7 mm gaps that vary by 1-2% along n,
# and slices off the line by up to ~0.07 mm
geo_rd = Geometry(row=(1, 0, 0), col=rotation((1, 0, 0), 12)[:, 1], spacing=(0.9375, 0.9375, 6.972),
                  p0=(-15.3, -48.2, -61.7))
pos = [np.round(geo_rd.position(k), 1) for k in range(MRI_U16.shape[0])]
_, uniform, warning, _, _ = placed("rounded", MRI_U16, MRI_U16, geo_rd, pos, modality="MR", sop_class=MR_IMAGE,
                                   description="T2 axial oblique, positions to 0.1 mm")
assert MRI_U16.shape[0] >= 20 and not uniform and warning, "rounded: the rounding must make the gaps uneven"

# "two_spacings": 2.5 mm gaps, then 5 mm gaps from slice 16 on (a CT
# reconstructed with two increments); the 5 mm gaps are 2x the median
geo_ts = Geometry(spacing=(0.7, 0.8, 2.5), p0=(-14.0, -12.5, 10.0))
z = np.concatenate([np.arange(16) * 2.5, 15 * 2.5 + np.arange(1, CT.shape[0] - 15) * 5.0])
pos = [geo_ts.p0 + zk * geo_ts.n for zk in z]
_, uniform, warning, _, _ = placed("two_spacings", CT_STORED, CT, geo_ts, pos, bits_stored=12, slope=1,
                                   intercept=-1024)
assert not uniform and warning


# "tilt15": a 15 degree gantry tilt: every slice shifted along the column
# direction by gap * tan(15 degrees) more than the one before, the
# orientation unchanged (axial), Gantry/Detector Tilt (0018,1120) = 15
def gantry(k, ds):
    ds.GantryDetectorTilt = "15"


pos = [geo_ct.position(k) + k * geo_ct.spacing[2] * np.tan(np.radians(15)) * geo_ct.col for k in range(CT.shape[0])]
_, uniform, warning, tilt, _ = placed("tilt15", CT_STORED, CT, geo_ct, pos, bits_stored=12, slope=1,
                                      intercept=-1024, edit=gantry)
assert not uniform and not warning and abs(tilt - 15) < 1e-6, tilt

# "missing_slice": slice 11 of a uniform series removed: a gap of 2x the median
keep = [k for k in range(CT.shape[0]) if k != 11]
pos = [geo_ct.position(k) for k in keep]
_, uniform, warning, _, long_gaps = placed("missing_slice", CT_STORED[keep], CT[keep], geo_ct, pos,
                                           bits_stored=12, slope=1, intercept=-1024)
assert not uniform and warning and long_gaps == 1

# "irregular": slice 9 moved by 0.3 gap along n (the old refusal, now meshed)
pos = [geo_ct.position(k) + (0.3 * geo_ct.spacing[2] * geo_ct.n if k == 9 else 0) for k in range(CT.shape[0])]
_, uniform, warning, _, long_gaps = placed("irregular", CT_STORED, CT, geo_ct, pos, bits_stored=12, slope=1,
                                           intercept=-1024)
assert not uniform and warning and long_gaps == 0

# ---------------------------------------------------------------- defects

def defect(name, status, substring, edit=None, drop=None, stored=None, geo=geo_ct, names="dcm", extra=None):
    f = d(name)
    st = stored if stored is not None else (CT.astype(np.int32) + 1024).astype(np.uint16)
    paths = write_series(f, st, geo, bits_stored=12, slope=1, intercept=-1024, names=names, edit=edit)
    if drop is not None:
        os.remove(paths[drop])
    if extra:
        extra(f, paths)
    error(name, status, substring, [f])
    return paths


def dup(f, paths):
    ds = pydicom.dcmread(paths[5])
    ds.SOPInstanceUID = generate_uid()
    ds.save_as(os.path.join(f, "copy_of_slice5.dcm"))


defect("duplicate", MISMATCH, "at the same position", extra=dup)


def other_size(f, paths):
    ds = pydicom.dcmread(paths[4])
    arr = ds.pixel_array[:-2]
    ds.Rows = arr.shape[0]
    ds.PixelData = arr.tobytes()
    ds.save_as(paths[4])


defect("size_differs", MISMATCH, "size 40x34 differs", extra=other_size)


def turned(k, ds):
    if k == 6:
        ds.ImageOrientationPatient = ["1", "0", "0", "0", "0.9", "-0.43588989"]


defect("orientation_differs", MISMATCH, "Image Orientation (Patient)", edit=turned)


def truncate(f, paths):
    size = os.path.getsize(paths[3])
    with open(paths[3], "r+b") as fp:
        fp.truncate(size - 1000)


defect("truncated", CORRUPT, "truncated", extra=truncate)


def garbage(f, paths):
    with open(paths[2], "r+b") as fp:
        fp.seek(132)
        fp.write(bytes(RNG.integers(0, 256, 400, dtype=np.uint8)))


defect("corrupt_header", CORRUPT, "corrupt", extra=garbage)


def no_spacing(k, ds):
    del ds.PixelSpacing


defect("no_pixel_spacing", UNSUPPORTED, "no Pixel Spacing", edit=no_spacing)

# RLE with a fragment cut in half: the decoder refuses it, naming the file
f = d("rle_corrupt")
paths = write_series(f, (CT.astype(np.int32) + 1024).astype(np.uint16), geo_ct, bits_stored=12, slope=1,
                     intercept=-1024, syntax=RLELossless, names="dcm")
from pydicom.encaps import decode_data_sequence, encapsulate
ds = pydicom.dcmread(paths[7])
frag = decode_data_sequence(ds.PixelData)[0]
ds.PixelData = encapsulate([frag[:len(frag) // 2]])
ds.save_as(paths[7])
error("rle_corrupt", CORRUPT, "RLE frame 1", [f])

f = d("only_reports")
text_sr(f)
open(os.path.join(f, "notes.txt"), "w").write("x\n")
error("only_reports", NOT_FOUND, "no DICOM image", [f])


def colour(f, paths):
    for p in paths:
        ds = pydicom.dcmread(p)
        g = ds.pixel_array.astype(np.uint8)
        rgb = np.stack([g, g, g], axis=-1)
        ds.SamplesPerPixel = 3
        ds.PhotometricInterpretation = "RGB"
        ds.PlanarConfiguration = 0
        ds.BitsAllocated = ds.BitsStored = 8
        ds.HighBit = 7
        ds.PixelData = rgb.tobytes()
        ds.save_as(p)


defect("colour", UNSUPPORTED, "a colour image", extra=colour)

with open(os.path.join(OUT, "manifest.tsv"), "w") as fp:
    fp.write("\n".join(LINES) + "\n")
with open(os.path.join(OUT, "cases.json"), "w") as fp:
    json.dump(CASES, fp, indent=1)
print("gen_dicom: %d cases in %s" % (len(LINES), OUT))
