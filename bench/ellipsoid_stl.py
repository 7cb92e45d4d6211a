"""Writes a finely subdivided ellipsoid as a binary STL file, for the mesh-size benchmark
(bench/mesh_size.sh): a closed, consistently oriented UV mesh of about TRIANGLES triangles.

    python bench/ellipsoid_stl.py OUT.stl TRIANGLES [A B C]

A, B, C are the semi-axes in metres (default 0.055 0.045 0.040, the ellipsoid of
config/ellipsoid_spatial.toml). The mesh has `lon` segments around z and `lat` bands from
pole to pole (`lon` about sqrt(TRIANGLES), `lat` = TRIANGLES / (2 lon) + 1, odd, so no ring
lies in the plane z = 0 through the centre of mass): 2 lon (lat - 1) triangles, the bands'
quads split in two, triangle fans at the poles, counter-clockwise seen from outside. Prints
`lon lat triangles` to stdout. Needs numpy only.
"""

import sys

import numpy as np


def ellipsoid(triangles: int, a: float, b: float, c: float):
    lon = max(3, round(triangles**0.5))
    lat = max(3, triangles // (2 * lon) + 1)
    if lat % 2 == 0:
        lat += 1
    theta = np.pi * np.arange(1, lat) / lat  # polar angle of the rings
    phi = 2 * np.pi * np.arange(lon) / lon
    st, ct = np.sin(theta)[:, None], np.cos(theta)[:, None]
    ring = np.stack(
        [a * st * np.cos(phi), b * st * np.sin(phi), c * np.broadcast_to(ct, (lat - 1, lon))],
        axis=-1,
    ).reshape(-1, 3)
    north, south = np.array([[0.0, 0.0, c]]), np.array([[0.0, 0.0, -c]])
    vertices = np.concatenate([north, ring, south])
    index = lambda i, j: 1 + i * lon + (j % lon)  # ring i (from the north), segment j
    j = np.arange(lon)
    faces = [np.stack([np.zeros(lon, int), index(0, j), index(0, j + 1)], axis=1)]
    for i in range(lat - 2):
        p, q, r, s = index(i, j), index(i + 1, j), index(i + 1, j + 1), index(i, j + 1)
        faces.append(np.stack([p, q, r], axis=1))
        faces.append(np.stack([p, r, s], axis=1))
    last = len(vertices) - 1
    faces.append(np.stack([index(lat - 2, j), np.full(lon, last), index(lat - 2, j + 1)], axis=1))
    return lon, lat, vertices, np.concatenate(faces)


def write_stl(path: str, vertices: np.ndarray, faces: np.ndarray) -> None:
    corners = vertices[faces]  # (n, 3, 3)
    normals = np.cross(corners[:, 1] - corners[:, 0], corners[:, 2] - corners[:, 0])
    normals /= np.linalg.norm(normals, axis=1, keepdims=True)
    record = np.dtype([("normal", "<f4", 3), ("corners", "<f4", (3, 3)), ("attribute", "<u2")])
    data = np.zeros(len(faces), dtype=record)
    data["normal"] = normals
    data["corners"] = corners
    with open(path, "wb") as f:
        f.write(b"binary STL: icrflow bench/ellipsoid_stl.py".ljust(80, b" "))
        f.write(np.uint32(len(faces)).tobytes())
        data.tofile(f)


def main() -> int:
    out, triangles = sys.argv[1], int(sys.argv[2])
    a, b, c = (float(x) for x in sys.argv[3:6]) if len(sys.argv) >= 6 else (0.055, 0.045, 0.040)
    lon, lat, vertices, faces = ellipsoid(triangles, a, b, c)
    write_stl(out, vertices, faces)
    print(lon, lat, len(faces))
    return 0


if __name__ == "__main__":
    sys.exit(main())
