#!/usr/bin/env python3
"""Blender's own check of the extension package (ctest blender_extension_validate,
Blender 4.2+):

    blender -b --factory-startup --command extension validate ZIP

The package passes when Blender exits with 0 and its last message is
`Success parsing TOML in "ZIP"` (only Blender's version banner, printed at exit,
may follow), with no error line.  Blender 4.3 prints that line only after every
check (the manifest's fields, its tags, __init__.py in the archive); a refusal
prints `FATAL_ERROR: Error ...` or `Error extracting archive ...` and exits
with 1.  (A pass regex in CTest would ignore the exit code; this script
checks both.)

So that the test can fail, the same command first runs on copies of the
package: one rewritten without a change, which must pass the same way, then
copies broken on purpose, which Blender must refuse: exit code not 0, no
success line, a line with the reason.  The copies leave out lib/ (the bundled
libraries, most of the package's bytes), which `validate` does not read: it
reads the manifest and the list of files.

Usage: validate_extension.py --blender EXE --package ZIP --work DIR
"""
import argparse
import os
import re
import shutil
import subprocess
import sys
import zipfile

sys.dont_write_bytecode = True  # no __pycache__ in the source tree
sys.path.insert(0, os.path.join(os.path.dirname(os.path.abspath(__file__)), "..", "common"))
import clitest  # noqa: E402
from clitest import fail  # noqa: E402

SUCCESS = 'Success parsing TOML in "%s"'
BANNER = re.compile(r"^Blender \d+\.\d+")
ERROR = re.compile(r"FATAL|[Ee]rror|Traceback")
MANIFEST = "blender_manifest.toml"


def validate(blender, env, path):
    """Runs `extension validate` on path -> (exit code, output lines)."""
    r = subprocess.run([blender, "-b", "--factory-startup", "--command", "extension", "validate", path],
                       capture_output=True, text=True, env=env, timeout=100)
    print("$ extension validate %s: exit %d\n%s%s" % (os.path.basename(path), r.returncode, r.stdout, r.stderr))
    return r.returncode, r.stdout.splitlines(), r.stderr.splitlines()


def accepted(blender, env, path):
    """The reasons `path` is not accepted (empty: accepted)."""
    rc, out, err = validate(blender, env, path)
    problems = []
    if rc != 0:
        problems.append("exit code %d" % rc)
    errors = [line for line in out + err if ERROR.search(line)]
    if errors:
        problems.append("error lines %s" % errors)
    # The success line, then at most Blender's version banner.
    tail = [line for line in out if line.strip() and not BANNER.match(line)]
    if not tail or tail[-1] != SUCCESS % path:
        problems.append("the last message is %r, not %r" % (tail[-1] if tail else None, SUCCESS % path))
    return problems


def refused(blender, env, path, reason):
    """The reasons `path` is not refused with `reason` (empty: refused)."""
    rc, out, err = validate(blender, env, path)
    problems = []
    if rc == 0:
        problems.append("exit code 0")
    if any(line.startswith("Success parsing TOML") for line in out + err):
        problems.append("a success line")
    if not any(reason in line for line in out + err):
        problems.append("no line with %r" % reason)
    return problems


def copy(package, out, edit):
    """Writes a copy of the package without lib/, `edit(name, data)` giving
    each entry's new bytes (None: left out); whether the edit changed any."""
    changed = False
    with zipfile.ZipFile(package) as src, zipfile.ZipFile(out, "w", zipfile.ZIP_DEFLATED) as dst:
        for info in src.infolist():
            if info.filename.startswith("lib/"):
                continue
            data = src.read(info)
            new = edit(info.filename, data)
            changed |= new != data
            if new is not None:
                dst.writestr(info, new)
    return changed


def manifest_edit(old, new):
    def edit(name, data):
        return data.replace(old.encode(), new.encode(), 1) if name.endswith(MANIFEST) else data
    return edit


def main():
    ap = argparse.ArgumentParser()
    for opt in ("--blender", "--package", "--work"):
        ap.add_argument(opt, required=True)
    a = ap.parse_args()
    shutil.rmtree(a.work, ignore_errors=True)
    os.makedirs(a.work)
    env = dict(os.environ, HOME=a.work)
    package = os.path.abspath(a.package)
    if not zipfile.is_zipfile(package):
        fail("the package", "%s is not a zip file" % package)
        return clitest.summary()

    # The controls: a rewritten copy passes, broken copies are refused.
    control = os.path.join(a.work, "copy.zip")
    copy(package, control, lambda name, data: data)
    for p in accepted(a.blender, env, control):
        fail("the unchanged copy", p)
    broken = [
        ("no_schema_version", manifest_edit('schema_version = "1.0.0"\n', ""),
         'missing "schema_version"'),
        ("unknown_tag", manifest_edit('tags = ["Import-Export", "Mesh"]', 'tags = ["Import-Export", "No Such Tag"]'),
         'found invalid tag "No Such Tag"'),
        ("no_init", lambda name, data: None if name in ("__init__.py", "isomend_import/__init__.py") else data,
         'file missing from add-on: "__init__.py"'),
    ]
    for name, edit, reason in broken:
        path = os.path.join(a.work, name + ".zip")
        if not copy(package, path, edit):
            fail(name, "the package has nothing to break (its manifest or files changed?)")
            continue
        for p in refused(a.blender, env, path, reason):
            fail(name, p)
    not_zip = os.path.join(a.work, "not_a_zip.zip")
    with open(not_zip, "w") as f:
        f.write("not a zip\n")
    for p in refused(a.blender, env, not_zip, "Error extracting archive"):
        fail("not_a_zip", p)

    # The package itself.
    for p in accepted(a.blender, env, package):
        fail("the package", p)

    if not clitest.failures:
        shutil.rmtree(a.work)
    return clitest.summary(ok="ok: Blender validates the package and refuses %d broken copies"
                           % (len(broken) + 1))


if __name__ == "__main__":
    sys.exit(main())
