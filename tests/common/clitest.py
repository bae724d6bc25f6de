"""What the Python tests that drive the `isomend` command line share.

Used by tests/io/test_cli_io.py, tests/io/test_dicom_cli.py,
tests/cli/test_cli.py, test_stream.py and test_stream_memory.py, which import it with their own folder's ../common on
sys.path.  Standard library only (test_cli.py runs in the sanitizer build
too); read_ply_arrays imports numpy when it is called.
"""
import subprocess

failures = []


def check(cond, what):
    """Records (and prints) a failure unless `cond`; the test goes on."""
    if not cond:
        failures.append(what)
        print("FAIL:", what, flush=True)


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


def summary(failures):
    """The last line of a test: the number of failures, or ok; the exit code."""
    if failures:
        print(f"{len(failures)} failure(s)")
        return 1
    print("ok")
    return 0
