#!/usr/bin/env python3
"""A real DICOM series from a Debian package: the enhanced (multi-frame) MR of
Debian 12's python3-nibabel test data, nibabel/nicom/tests/data/
philips_mprage.dcm.gz (a Philips 3D T1 MPRAGE, 256 x 256 x 176 frames, sagittal
and slightly oblique, per-frame positions and rescale; nibabel's test data,
MIT/Expat, see samples/LICENSE-nibabel.txt).  Its pixel data were zeroed by
whoever anonymised it, so this test is about reading a scanner's file and its
geometry, not about a surface.

Checks, against the file's own values read independently with pydicom:
- `isomend info --json`: kind dicom, one multi-frame file, 256 x 256 x 176,
  f32 (the slope 2.1079365 is not an integer), modality MR, spacing 1, 1 and
  the measured slice distance;
- every frame's Image Position (Patient) is the world position of sample
  (0, 0, k) for its slot k, and the slots follow the positions along the
  normal; the in-plane axes follow the row and column direction cosines times
  the column and row spacings (LPS mm), i.e. the patient transform is the
  scanner's;
- every decoded value is 0 (as stored), and extract without --iso refuses:
  no surface exists.

Usage: test_dicom_real.py ISOMEND_CLI
"""
import gzip
import json
import os
import shutil
import subprocess
import sys
import tempfile

import numpy as np
import pydicom

sys.path.insert(0, os.path.join(os.path.dirname(os.path.abspath(__file__)), "..", "common"))
from clitest import check, summary  # noqa: E402

CLI = sys.argv[1]
SRC = "/usr/lib/python3/dist-packages/nibabel/nicom/tests/data/philips_mprage.dcm.gz"


if not os.path.exists(SRC):
    print("FAIL: %s missing: install python3-nibabel (scripts/deps.sh does)" % SRC)
    sys.exit(1)

with tempfile.TemporaryDirectory() as tmp:
    path = os.path.join(tmp, "philips_mprage.dcm")
    with gzip.open(SRC) as fi, open(path, "wb") as fo:
        shutil.copyfileobj(fi, fo)
    r = subprocess.run([CLI, "info", path, "--json", "-", "--quiet"], capture_output=True, text=True)
    check(r.returncode == 0, "info: %s" % r.stderr)
    j = json.loads(r.stdout)
    d = j["dicom"]
    check(j["kind"] == "dicom" and j["dims"] == [256, 256, 176] and j["type"] == "f32",
          "kind/dims/type %s %s %s" % (j["kind"], j["dims"], j["type"]))
    check(d["modality"] == "MR" and d["multiframe"] and d["files"] == 1 and not d["hounsfield"],
          "dicom %s" % d)
    check(abs(d["rescale_slope"] - 2.1079365079365) < 1e-9 and j["suggested_level"] == "otsu",
          "rescale %s" % d["rescale_slope"])

    ds = pydicom.dcmread(path)
    frames = ds.PerFrameFunctionalGroupsSequence
    ipp = np.array([[float(v) for v in f.PlanePositionSequence[0].ImagePositionPatient] for f in frames])
    iop = np.array([float(v) for v in frames[0].PlaneOrientationSequence[0].ImageOrientationPatient])
    ps = [float(v) for v in frames[0].PixelMeasuresSequence[0].PixelSpacing]
    row, col = iop[:3], iop[3:]
    n = np.cross(row, col)
    order = np.argsort(ipp @ n, kind="stable")
    W = np.array(j["world_transform"]).reshape(3, 4)
    sp, org = np.array(j["spacing"]), np.array(j["origin"])

    def world(i, jj, k):
        return W[:, :3] @ (org + sp * np.array([i, jj, k], float)) + W[:, 3]

    check(np.allclose(sp[:2], [ps[1], ps[0]]), "pixel spacing %s vs %s" % (sp, ps))
    dist = np.linalg.norm(ipp[order[-1]] - ipp[order[0]]) / 175
    check(abs(sp[2] - dist) < 1e-6, "slice spacing %s, measured %s" % (sp[2], dist))
    worst = max(np.abs(world(0, 0, k) - ipp[order[k]]).max() for k in range(176))
    check(worst < 1e-3, "frame positions off by %g mm" % worst)
    check(np.allclose(world(1, 0, 0) - world(0, 0, 0), row * ps[1], atol=1e-6) and
          np.allclose(world(0, 1, 0) - world(0, 0, 0), col * ps[0], atol=1e-6),
          "in-plane axes are not the direction cosines")
    check(np.allclose(d["orientation"], iop) and np.allclose(d["normal"], n / np.linalg.norm(n), atol=1e-9),
          "orientation %s normal %s" % (d["orientation"], d["normal"]))
    check(j["min"] == 0 and j["max"] == 0 and not np.any(ds.pixel_array), "values %s..%s" % (j["min"], j["max"]))
    out = os.path.join(tmp, "m.ply")
    r = subprocess.run([CLI, "extract", path, "-o", out], capture_output=True, text=True)
    check(r.returncode == 2 and "no suggested level" in r.stderr and not os.path.exists(out),
          "extract of the zeroed series: %d %s" % (r.returncode, r.stderr))

sys.exit(summary())
