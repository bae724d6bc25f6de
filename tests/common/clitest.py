"""What the Python tests that drive the `isomend` command line share.

Used by the Python tests of tests/cli, tests/io and tests/mpi and by
tests/blender/validate_extension.py, which import it with their own folder's
../common on sys.path.  Standard library only (test_cli.py runs in the
sanitizer build too); read_ply_arrays, read_nrrd and busy_slice import numpy
when they are called.

A test's verdict: check() and fail() record failures in `failures` and the test
goes on; its main returns summary(), the exit code (1 with any failure), which
is what CTest judges (no PASS_REGULAR_EXPRESSION: that would ignore it).
"""
import os
import subprocess
import sys

failures = []


def check(cond, what):
    """Records (and prints) a failure unless `cond`; the test goes on."""
    if not cond:
        failures.append(what)
        print("FAIL:", what, flush=True)


def fail(name, why):
    """Records the failure `name: why` and prints it on standard error
    (after what standard output holds so far); the test goes on."""
    failures.append(f"{name}: {why}")
    sys.stdout.flush()
    print(f"FAIL {name}: {why}", file=sys.stderr, flush=True)


def failed(name):
    """Whether a failure of `name` (fail(name, ...)) has been recorded."""
    return any(x.startswith(name) for x in failures)


def run(cli, args):
    """Runs the command line with `args`; its output is captured as text."""
    return subprocess.run([cli] + args, capture_output=True, text=True)


def read_ply_header(data):
    """The header of a binary little-endian PLY as isomend writes it (bytes)
    -> (offset of the vertices, vertex count, face count, the names of the
    vertices' float properties)."""
    end = data.index(b"end_header\n") + len(b"end_header\n")
    header = data[:end].decode().splitlines()
    assert header[1] == "format binary_little_endian 1.0", header[1]
    nv = nf = 0
    props = []
    for line in header:
        w = line.split()
        if w[:2] == ["element", "vertex"]:
            nv = int(w[2])
        elif w[:2] == ["element", "face"]:
            nf = int(w[2])
        elif w[:2] == ["property", "float"]:
            props.append(w[2])
    return end, nv, nf, props


def read_ply_arrays(path):
    """isomend's binary PLY -> (vertices, triangles) as numpy arrays: float32,
    a row per vertex and a column per float property; uint32, the three vertex
    indices of each face (isomend writes triangles)."""
    import numpy as np

    data = open(path, "rb").read()
    end, nv, nf, props = read_ply_header(data)
    verts = np.frombuffer(data, dtype="<f4", count=nv * len(props), offset=end).reshape(nv, len(props))
    faces = np.frombuffer(data, dtype=np.dtype([("n", "u1"), ("v", "<u4", 3)]), count=nf,
                          offset=end + nv * len(props) * 4)
    return verts, faces["v"]


def read_nrrd(path):
    """samples/anatomical.nrrd (attached, gzip, int16) -> a numpy array [z, y, x]."""
    import gzip

    import numpy as np

    raw = open(path, "rb").read()
    head, _, body = raw.partition(b"\n\n")
    fields = dict(l.split(": ", 1) for l in head.decode().splitlines()[1:] if ": " in l and not l.startswith("#"))
    sizes = [int(v) for v in fields["sizes"].split()]
    assert fields["type"] == "int16" and fields["encoding"] == "gzip"
    return np.frombuffer(gzip.decompress(body), "<i2").reshape(sizes[::-1])


def run_measured(peak_rss, args, cwd, env=None, timeout=600):
    """Runs args; returns (exit code, stdout, stderr, peak resident bytes).

    Through peak_rss (tests/common/peak_rss.c), wait4's ru_maxrss of a child
    forked by a small C program: Linux keeps the high-water mark across exec,
    so a child forked by this Python process would report Python's own peak.
    For mpirun, the peak is the largest of mpirun's and the ranks' it waited for.
    """
    peak_file = os.path.join(cwd, "peak.txt")
    p = subprocess.run([peak_rss, peak_file, *args], cwd=cwd, capture_output=True, text=True,
                       stdin=subprocess.DEVNULL, timeout=timeout, env=env)
    with open(peak_file) as f:
        peak = int(f.read())
    return p.returncode, p.stdout, p.stderr, peak


def same_file(a, b):
    """Whether two (large) files hold the same bytes."""
    if os.path.getsize(a) != os.path.getsize(b):
        return False
    with open(a, "rb") as f, open(b, "rb") as g:
        while True:
            x, y = f.read(1 << 22), g.read(1 << 22)
            if x != y:
                return False
            if not x:
                return True


def busy_slice(k, nx=512, ny=512):
    """Slice k of a smooth, busy u16 field: about 75 000 triangles a 512^2 slice at iso 1000."""
    import numpy as np
    x = np.arange(nx, dtype=np.float32)[None, :]
    y = np.arange(ny, dtype=np.float32)[:, None]
    s = 1000 + 800 * np.sin(x * 0.21 + k * 0.05) * np.cos(y * 0.15) + 600 * np.sin(k * 0.12 + y * 0.06)
    return s.astype("<u2")


def mpi_env():
    """The environment for mpirun in the tests: no $DISPLAY (hwloc's GL plugin,
    loaded by Open MPI, talks to it: an Xvfb of another test that goes away
    mid-run kills the rank with "XIO: fatal IO error"), root allowed,
    oversubscription (2 cores, up to 5 ranks)."""
    env = {k: v for k, v in os.environ.items() if k != "DISPLAY"}
    env.update(OMPI_ALLOW_RUN_AS_ROOT="1", OMPI_ALLOW_RUN_AS_ROOT_CONFIRM="1",
               OMPI_MCA_rmaps_base_oversubscribe="1", HWLOC_COMPONENTS="-gl")
    return env


def summary(recorded=None, ok="ok"):
    """The last line of a test: the number of failures (of `recorded`, by
    default the ones check() and fail() recorded), or `ok`; the exit code."""
    recorded = failures if recorded is None else recorded
    if recorded:
        print(f"{len(recorded)} failure(s)", flush=True)
        return 1
    print(ok, flush=True)
    return 0
