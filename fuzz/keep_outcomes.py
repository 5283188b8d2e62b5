#!/usr/bin/env python3
"""Keeps one input per distinct outcome of a fuzz target's corpus.

Usage: fuzz/keep_outcomes.py TARGET CORPUS_DIR OUT_DIR
  TARGET: load_obj or load_gltf (decides the extension each input is loaded
  with, as the fuzz target does). Each input is loaded with `vis5d info`
  (release build); its outcome is "ok", or its error message without the
  file name, quoted text and paths, digits as "n", reduced to a
  40-character slug. The smallest
  input of each outcome is copied to OUT_DIR/<slug>.<ext>, so that
  `tests/it/obj_load.rs` and `gltf_load.rs` replay one input per outcome.
"""
import os, re, shutil, subprocess, sys, tempfile

target, corpus, out = sys.argv[1:4]
vis5d = os.path.join(os.path.dirname(__file__), "..", "target", "release", "vis5d")
os.makedirs(out, exist_ok=True)
kept = {}
with tempfile.TemporaryDirectory() as tmp:
    for name in sorted(os.listdir(corpus), key=lambda n: os.path.getsize(os.path.join(corpus, n))):
        data = open(os.path.join(corpus, name), "rb").read()
        if target == "load_obj":
            ext = "obj"
        else:
            ext = "glb" if data.startswith(b"glTF") else "gltf"
        path = os.path.join(tmp, "input." + ext)
        open(path, "wb").write(data)
        r = subprocess.run([vis5d, "info", path], capture_output=True, timeout=60)
        if r.returncode == 0:
            slug = "ok"
        elif r.returncode == 2:
            msg = r.stderr.decode("utf-8", "replace").split(path, 1)[-1]
            # What the input itself contributes (quoted text, paths) is not
            # part of the outcome.
            msg = re.sub(r'"[^"]*"', "", msg)
            msg = re.sub(r"\S*/\S*", "", msg)
            slug = re.sub(r"[0-9]+", "n", msg.lower())
            slug = re.sub(r"[^a-z]+", "_", slug).strip("_")[:40].rstrip("_")
        else:
            sys.exit(f"{name}: exit {r.returncode} (a crash?): {r.stderr[-500:]!r}")
        key = f"{slug}.{ext}"
        if key not in kept:
            kept[key] = name
            shutil.copy(os.path.join(corpus, name), os.path.join(out, key))
print(f"{len(kept)} outcomes kept in {out}")
