#!/usr/bin/python3
"""Every relative link in the project's Markdown files points at a file that exists and,
with a #fragment, at a heading of that file (GitHub's anchor rules).

Usage: check_links.py ROOT   (exit 1 and one line per broken link)
"""
import os
import re
import sys

LINK = re.compile(r"!?\[[^\]]*\]\(([^)\s]+)\)")


def anchors(path):
    out, fence = set(), False
    seen = {}
    for line in open(path, encoding="utf-8"):
        if line.startswith("```"):
            fence = not fence
        if fence or not line.startswith("#"):
            continue
        title = line.lstrip("#").strip().lower()
        slug = re.sub(r"[^\w\- ]", "", title).replace(" ", "-")
        n = seen.get(slug, 0)
        seen[slug] = n + 1
        out.add(slug if n == 0 else "%s-%d" % (slug, n))
    return out


def main(root):
    bad = []
    for dirpath, dirs, files in os.walk(root):
        dirs[:] = [d for d in dirs if not d.startswith((".", "build")) and d != "_deps"]
        for f in files:
            if not f.endswith(".md"):
                continue
            path = os.path.join(dirpath, f)
            fence = False
            for no, line in enumerate(open(path, encoding="utf-8"), 1):
                if line.startswith("```"):
                    fence = not fence
                if fence:
                    continue
                for target in LINK.findall(line):
                    if re.match(r"^[a-z]+:", target):
                        continue  # http:, mailto:
                    file, _, frag = target.partition("#")
                    dest = os.path.normpath(os.path.join(dirpath, file)) if file else path
                    rel = os.path.relpath(path, root)
                    if not os.path.exists(dest):
                        bad.append("%s:%d: %s: no such file" % (rel, no, target))
                    elif frag and dest.endswith(".md") and frag not in anchors(dest):
                        bad.append("%s:%d: %s: no such heading" % (rel, no, target))
    for b in bad:
        print(b)
    print("%d broken link(s)" % len(bad))
    return 1 if bad else 0


if __name__ == "__main__":
    sys.exit(main(sys.argv[1] if len(sys.argv) > 1 else "."))
