#!/usr/bin/env python3
"""Writes the fuzz targets' seed corpus into tests/fuzz/corpus/<target>/ from the repository's
own scenes and a tiny real bake, render and compressed bake made by the release binary
(`cargo build --release` first). Run from the repository root: python3 tests/fuzz/seeds.py"""

import os
import shutil
import struct
import subprocess
import sys
import tempfile

ROOT = os.getcwd()
LENSMAP = os.path.join(ROOT, "target/release/lensmap")
CORPUS = os.path.join(ROOT, "tests/fuzz/corpus")

SMALL = open(os.path.join(ROOT, "tests/src/fixtures.rs")).read().split('pub const SMALL_SCENE: &str = r#"')[1].split('"#;')[0]


def write(target, name, data):
    os.makedirs(os.path.join(CORPUS, target), exist_ok=True)
    with open(os.path.join(CORPUS, target, name), "wb") as f:
        f.write(data if isinstance(data, bytes) else data.encode())


def lensmap(*args):
    subprocess.run([LENSMAP, *args, "-q"], check=True)


def pack(files):
    """The bake archive of tests/fuzz/src/readers.rs (unpack)."""
    out = b""
    for name, data in files:
        out += bytes([len(name)]) + name.encode() + struct.pack("<I", len(data)) + data
    return out


def bake_archive(directory):
    names = sorted(os.listdir(directory), key=lambda n: (n != "manifest.json", n))
    return pack([(n, open(os.path.join(directory, n), "rb").read()) for n in names])


def main():
    shutil.rmtree(CORPUS, ignore_errors=True)
    work = tempfile.mkdtemp(prefix="lensmap-seeds-")
    try:
        # Scenes: every built-in and example scene, the tests' small scene, and the small scene
        # with each kind of asset (the harness puts mesh.obj, sky.exr and wood.png beside it).
        for folder in ("engine/scenes", "tools/scenes"):
            for name in sorted(os.listdir(os.path.join(ROOT, folder))):
                if name.endswith(".toml"):
                    write("scene", name, open(os.path.join(ROOT, folder, name), "rb").read())
        write("scene", "small.toml", SMALL)
        write("scene", "small-assets.toml", SMALL
              .replace("plane = { size = [4, 4] }", 'obj = { path = "mesh.obj" }')
              .replace("constant = [0.1, 0.1, 0.1]", 'latlong = { path = "sky.exr", scale = 2.0 }')
              .replace("diffuse = { colour = [0.5, 0.5, 0.5] }", 'diffuse = { image = "wood.png" }'))
        write("scene", "small-lens.toml", SMALL + '\n[[lenses]]\nname = "lens"\nobjects = ["ball"]\n'
              'layers = [{ sphere = 3.0 }]\n\n[view_space]\nlist = [[0, 1, 5], [1, 1, 5]]\n')

        # Assets: the first byte picks the kind (readers::ASSET_KINDS): 0 OBJ floor, 1 sky,
        # 2 texture, 3 OBJ floor smoothed. Images from a tiny real render.
        lensmap("render", "--scene", "glass-sphere", "--projected", "--em-size", "8", "--width", "8",
                "--height", "4", "--supersampling", "1", "--out", os.path.join(work, "frame.png"))
        png = open(os.path.join(work, "frame.png"), "rb").read()
        exr = open(os.path.join(work, "frame.exr"), "rb").read()
        obj = b"v 0 0 0\nv 1 0 0\nv 0 0 1\nv 1 0 1\nvt 0 0\nvt 1 0\nvt 0 1\nvt 1 1\nvn 0 1 0\nf 1/1/1 3/3/1 2/2/1\nf 2/2/1 3/3/1 4/4/1\n"
        write("asset", "obj-quad", b"\x00" + obj)
        write("asset", "obj-quad-smooth", b"\x03" + obj.replace(b"/1\n", b"\n").replace(b"/1 ", b" "))
        write("asset", "obj-groups", b"\x00o a\nv 0 0 0\nv 1 0 0\nv 0 0 1\nf 1 3 2\ng b\nv 0 1 0\nf -1 -2 -3\nusemtl m\ns 1\n")
        write("asset", "obj-nan-normal", b"\x00v 0 0 0\nv 1 0 0\nv 0 0 1\nvn nan 1 0\nf 1//1 2//1 3//1\n")
        write("asset", "obj-polyline", b"\x00v 0 0 0\nv 1 0 0\nv 0 0 1\nl 1 2 3\n")
        write("asset", "sky-exr", b"\x01" + exr)
        write("asset", "sky-png", b"\x01" + png)
        write("asset", "texture-png", b"\x02" + png)
        write("asset", "texture-exr", b"\x02" + exr)

        # Bakes: a tiny real bake of glass-sphere (2 samples, 8² maps, 1 layer), compressed too.
        bake = os.path.join(work, "bake")
        lensmap("bake", "--scene", "glass-sphere", "--samples", "0,1", "--out", bake, "--width", "16",
                "--height", "12", "--supersampling", "1", "--em-size", "8", "--layers", "1",
                "--multi-view", "1", "--no-judge")
        compressed = os.path.join(work, "bake-compressed")
        lensmap("bake", "--compress", bake, "--out", compressed)
        write("bake", "glass-sphere-exr", bake_archive(bake))
        write("bake", "glass-sphere-compressed", bake_archive(compressed))
        manifest = open(os.path.join(bake, "manifest.json"), "rb").read()
        write("bake", "manifest-only", pack([("manifest.json", manifest)]))

        # The C ABI: programs of calls (tests/fuzz/src/capi.rs). Call 0: load the small scene with
        # projected 8² EMs; 3: render at the scene's own options; 5: a plan; 2: frame options;
        # 6: free; 7: validation messages.
        load = bytes([0, 0, 0, 0, 0, 0, 1, 0, 0])
        render = bytes([3]) + struct.pack("<I", 0) + bytes([3, 0, 1, 2])
        render_options = (bytes([3]) + struct.pack("<I", (1 << 5) | (1 << 6) | (1 << 8) | (1 << 9))
                          + struct.pack("<IIII", 8, 6, 1, 2) + bytes([3, 0, 1, 2]))
        plan = bytes([5]) + struct.pack("<IIIIII", 3, 2, 2, 1, 2, 0) + bytes([7, 0, 1])
        write("capi", "load-render", load + render)
        write("capi", "load-render-multipass", load + render_options)
        write("capi", "plan", plan)
        write("capi", "load-options-free", load + bytes([2, 3, 0]) + bytes([6, 7]) + render)
        write("capi", "load-scene-file", bytes([0, 2]) + struct.pack("<I", len(SMALL)) + SMALL.encode()
              + bytes([0, 0, 0, 0, 1, 0, 0]) + render)
        write("capi", "builtin-name", bytes([0, 3, 12]) + b"glass-sphere" + bytes([0, 0, 0, 0, 1, 0, 0]))
    finally:
        shutil.rmtree(work, ignore_errors=True)


if __name__ == "__main__":
    sys.exit(main())
