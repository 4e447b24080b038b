#!/usr/bin/env python3
"""Writes the binary twin of the hand-written text model in text/ to bin/.

The byte layout follows COLMAP's scripts/python/read_write_model.py (all
little endian): cameras.bin, images.bin and points3D.bin. Run it from any
directory: python3 tests/data/colmap/make_bin.py
"""
import os
import struct

MODEL_IDS = {
    "SIMPLE_PINHOLE": (0, 3), "PINHOLE": (1, 4), "SIMPLE_RADIAL": (2, 4), "RADIAL": (3, 5),
    "OPENCV": (4, 8), "OPENCV_FISHEYE": (5, 8), "FULL_OPENCV": (6, 12), "FOV": (7, 5),
    "SIMPLE_RADIAL_FISHEYE": (8, 4), "RADIAL_FISHEYE": (9, 5), "THIN_PRISM_FISHEYE": (10, 12),
}
HERE = os.path.dirname(os.path.abspath(__file__))


def data_lines(path):
    with open(path) as f:
        return [line.rstrip("\n") for line in f if line.strip() and not line.startswith("#")]


def cameras(src, dst):
    rows = [line.split() for line in data_lines(src)]
    with open(dst, "wb") as f:
        f.write(struct.pack("<Q", len(rows)))
        for cam_id, model, width, height, *params in rows:
            model_id, nparams = MODEL_IDS[model]
            assert len(params) == nparams, model
            f.write(struct.pack("<iiQQ", int(cam_id), model_id, int(width), int(height)))
            f.write(struct.pack("<%dd" % nparams, *map(float, params)))


def images(src, dst):
    # Two lines per image; the second (2D points) may be empty, so comments are
    # dropped but blank lines are kept here.
    with open(src) as f:
        lines = [line.rstrip("\n") for line in f if not line.startswith("#")]
    pairs = [(lines[i], lines[i + 1]) for i in range(0, len(lines) - 1, 2)]
    with open(dst, "wb") as f:
        f.write(struct.pack("<Q", len(pairs)))
        for head, pts in pairs:
            image_id, qw, qx, qy, qz, tx, ty, tz, cam_id, name = head.split()
            f.write(struct.pack("<i7di", int(image_id), *map(float, (qw, qx, qy, qz, tx, ty, tz)), int(cam_id)))
            f.write(name.encode() + b"\x00")
            vals = pts.split()
            f.write(struct.pack("<Q", len(vals) // 3))
            for i in range(0, len(vals), 3):
                f.write(struct.pack("<ddq", float(vals[i]), float(vals[i + 1]), int(vals[i + 2])))


def points3d(src, dst):
    rows = [line.split() for line in data_lines(src)]
    with open(dst, "wb") as f:
        f.write(struct.pack("<Q", len(rows)))
        for pid, x, y, z, r, g, b, err, *track in rows:
            f.write(struct.pack("<QdddBBBd", int(pid), float(x), float(y), float(z), int(r), int(g), int(b), float(err)))
            f.write(struct.pack("<Q", len(track) // 2))
            f.write(struct.pack("<%di" % len(track), *map(int, track)))


def main():
    src, dst = os.path.join(HERE, "text"), os.path.join(HERE, "bin")
    os.makedirs(dst, exist_ok=True)
    cameras(os.path.join(src, "cameras.txt"), os.path.join(dst, "cameras.bin"))
    images(os.path.join(src, "images.txt"), os.path.join(dst, "images.bin"))
    points3d(os.path.join(src, "points3D.txt"), os.path.join(dst, "points3D.bin"))


if __name__ == "__main__":
    main()
