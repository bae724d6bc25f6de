#!/usr/bin/python3
"""Runs a command with $DISPLAY set to a private Xvfb server.

Usage: with_xvfb.py COMMAND [ARGS...]
       (screen 1024x768x24, or $ISOMEND_XVFB_SCREEN)

Unlike `xvfb-run -a`, which probes for a free display number and can race
with another test doing the same under `ctest -j`, the server picks its own
free display (-displayfd) and reports it back.  The server is stopped when
the command ends; the command's exit status is returned.
"""
import os
import signal
import subprocess
import sys


def main():
    if len(sys.argv) < 2:
        sys.exit("usage: with_xvfb.py COMMAND [ARGS...]")
    read_fd, write_fd = os.pipe()
    server = subprocess.Popen(
        ["Xvfb", "-displayfd", str(write_fd), "-screen", "0",
         os.environ.get("ISOMEND_XVFB_SCREEN", "1024x768x24"), "-nolisten", "tcp"],
        pass_fds=(write_fd,), stdout=subprocess.DEVNULL, stderr=subprocess.PIPE)
    os.close(write_fd)
    number = b""
    with os.fdopen(read_fd, "rb") as f:
        while not number.endswith(b"\n"):
            chunk = f.read(1)
            if not chunk:
                break
            number += chunk
    if not number.strip().isdigit():
        err = server.stderr.read().decode(errors="replace") if server.poll() is not None else ""
        server.kill()
        sys.exit("with_xvfb.py: Xvfb did not start: " + err)
    env = dict(os.environ, DISPLAY=":" + number.strip().decode())
    env.pop("WAYLAND_DISPLAY", None)
    try:
        rc = subprocess.call(sys.argv[1:], env=env)
    finally:
        server.send_signal(signal.SIGTERM)
        try:
            server.wait(timeout=10)
        except subprocess.TimeoutExpired:
            server.kill()
    return rc


if __name__ == "__main__":
    sys.exit(main())
