#!/usr/bin/env python3
"""This machine's pip settings as a build secret: writes OUTDIR/pip.conf, prints build-volume flags.

    python3 docker/pipconf.py OUTDIR [--engine docker|podman]

``pip config list`` (files and PIP_* environment, the environment winning) becomes a pip.conf
that the Dockerfile mounts as the secret ``pipconf`` for its pip steps only, so a private index,
a CA bundle or constraints are used during the build and never stored in a layer. Certificate and
constraint files are copied into OUTDIR (mounted read-only at /run/host-pip); local index or
wheel directories are mounted read-only at their own paths (podman's ``build -v``; docker's
builder has no build volumes, so with docker they are left out and named on stderr). Prints one
``-v SRC:DST:ro`` pair per line for the build command. Without any pip settings the pip.conf is
empty and pip uses its defaults.
"""

from __future__ import annotations

import ast
import os
import shutil
import subprocess
import sys


def main(argv: list[str]) -> int:
    if not argv or argv[0].startswith("-"):
        print("error: usage: pipconf.py OUTDIR [--engine docker|podman]", file=sys.stderr)
        return 2
    out = argv[0]
    engine = argv[argv.index("--engine") + 1] if "--engine" in argv[:-1] else "podman"
    os.makedirs(out, exist_ok=True)
    listing = subprocess.run([sys.executable, "-m", "pip", "config", "list"], capture_output=True, text=True).stdout
    cfg: dict[str, str] = {}
    for line in listing.splitlines():
        key, _, val = line.strip().partition("=")
        if not val:
            continue
        section, _, opt = key.rpartition(".")
        if section == ":env:" or opt not in cfg:  # the environment wins over files
            cfg[opt] = str(ast.literal_eval(val))
    volumes: dict[str, str] = {os.path.abspath(out): "/run/host-pip"}
    for opt in ("cert", "client-cert"):
        if opt in cfg and os.path.isfile(cfg[opt]):
            shutil.copy(cfg[opt], os.path.join(out, opt + ".pem"))
            cfg[opt] = f"/run/host-pip/{opt}.pem"
    if "constraint" in cfg:
        files = []
        for i, f in enumerate(cfg["constraint"].split()):
            if os.path.isfile(f):
                shutil.copy(f, os.path.join(out, f"constraint{i}.txt"))
                files.append(f"/run/host-pip/constraint{i}.txt")
        cfg["constraint"] = " ".join(files)
    for opt in ("index-url", "extra-index-url", "find-links"):
        kept = []
        for tok in cfg.get(opt, "").split():
            path = tok[len("file://"):] if tok.startswith("file://") else tok
            if not path.startswith("/"):
                kept.append(tok)
                continue
            if not os.path.exists(path):
                continue
            if engine == "docker":
                print(f"pipconf: {opt} {tok} is a local directory; docker builds cannot mount it: left out",
                      file=sys.stderr)
                continue
            d = path.rstrip("/")
            d = os.path.dirname(d) if os.path.basename(d) == "simple" else d
            volumes[d] = d
            kept.append(tok)
        if opt in cfg:
            cfg[opt] = " ".join(kept)
    with open(os.path.join(out, "pip.conf"), "w", encoding="utf-8") as f:
        f.write("[global]\n" + "".join(f"{k} = {v}\n" for k, v in cfg.items() if v))
    if engine == "podman":
        for src, dst in volumes.items():
            print(f"-v\n{src}:{dst}:ro")
    return 0


if __name__ == "__main__":
    sys.exit(main(sys.argv[1:]))
