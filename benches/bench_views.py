"""Speed of the six depth views (rgbd_rs.shapes.views, thesis §5.3.1) against trimesh+Embree
and Open3D's RaycastingScene casting the same 6 x R x R orthographic rays at the same mesh, in
the same run; point-cloud views of ModelNet clouds (single and batch); LCN.

The mesh is the Stanford bunny subdivided once (14,696 faces). Peers get precomputed ray arrays
(not timed) and are timed twice: casting only, and building their scene + casting (the cost per
shape when a dataset is processed, which is what rgbd_rs's one call includes). "vs X" = X's
time / rgbd_rs's time (> 1: rgbd_rs is faster). Peers that cannot be imported are reported as
unavailable (Open3D needs the system library libusb-1.0).

    python benches/bench_views.py             # table on stdout
    python benches/bench_views.py --markdown  # the README table
"""

from __future__ import annotations

import argparse
import os
from collections.abc import Callable

import numpy as np

from _timing import timeit

REPEATS = 7
# The documented view axes (right, up, forward), to build the peers' rays.
AXES = [
    ((0, 1, 0), (0, 0, 1), (-1, 0, 0)),
    ((-1, 0, 0), (0, 0, 1), (0, -1, 0)),
    ((0, -1, 0), (0, 0, 1), (1, 0, 0)),
    ((1, 0, 0), (0, 0, 1), (0, 1, 0)),
    ((1, 0, 0), (0, 1, 0), (0, 0, -1)),
    ((-1, 0, 0), (0, 1, 0), (0, 0, 1)),
]


def rays(vertices: np.ndarray, res: int) -> tuple[np.ndarray, np.ndarray]:
    """Origins (on the near cube faces, slightly outside) and directions of all six views."""
    lo, hi = vertices.min(0).astype(np.float64), vertices.max(0).astype(np.float64)
    centre, side = (lo + hi) / 2, float((hi - lo).max())
    c = ((np.arange(res) + 0.5) / res - 0.5) * side
    x, y = np.meshgrid(c, -c)
    origins, dirs = [], []
    for right, up, fwd in AXES:
        r, u, f = (np.array(a, np.float64) for a in (right, up, fwd))
        o = centre + x[..., None] * r + y[..., None] * u - f * side * 0.501
        origins.append(o.reshape(-1, 3))
        dirs.append(np.broadcast_to(f, o.shape).reshape(-1, 3))
    return np.concatenate(origins), np.concatenate(dirs)


def peers(vertices: np.ndarray, faces: np.ndarray) -> dict[str, tuple[Callable, Callable]]:
    """name -> (build(), cast(built, origins, dirs)) for each importable peer."""
    out: dict[str, tuple[Callable, Callable]] = {}
    try:
        import trimesh
        from trimesh.ray.ray_pyembree import RayMeshIntersector

        def build_embree():  # type: ignore[no-untyped-def]
            return RayMeshIntersector(trimesh.Trimesh(vertices, faces, process=False))

        def cast_embree(s, o, d):  # type: ignore[no-untyped-def]
            return s.intersects_location(o, d, multiple_hits=False)

        out["trimesh+Embree"] = (build_embree, cast_embree)
    except Exception as e:
        print(f"trimesh+Embree unavailable: {e}")
    try:
        import open3d as o3d

        def build_o3d():  # type: ignore[no-untyped-def]
            s = o3d.t.geometry.RaycastingScene()
            s.add_triangles(
                o3d.core.Tensor(vertices.astype(np.float32)),
                o3d.core.Tensor(faces.astype(np.uint32)),
            )
            return s

        def cast_o3d(s, o, d):  # type: ignore[no-untyped-def]
            r = o3d.core.Tensor(np.concatenate([o, d], 1).astype(np.float32))
            return s.cast_rays(r)["t_hit"].numpy()

        out["Open3D RaycastingScene"] = (build_o3d, cast_o3d)
    except Exception as e:
        print(f"Open3D unavailable: {e}")
    return out


def main() -> None:
    ap = argparse.ArgumentParser(
        description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter
    )
    ap.add_argument("--markdown", action="store_true")
    args = ap.parse_args()

    import trimesh

    from rgbd_rs import _rgbd_rs
    from rgbd_rs.data import data_root
    from rgbd_rs.meshes import Mesh, load_mesh
    from rgbd_rs.shapes.views import (
        depth_views,
        depth_views_batch,
        lcn_window,
        local_contrast_normalize,
    )

    root = data_root(required=True)
    assert root is not None
    bunny = load_mesh(root / "meshes" / "stanford_bunny.off")
    v, f = trimesh.remesh.subdivide(bunny.vertices, bunny.triangles)
    mesh = Mesh(v.astype(np.float32), f.astype(np.uint32))
    pk = np.load(root / "modelnet" / "modelnet10_1024.npz")
    clouds = [p.astype(np.float32) for p in pk["points"][:64]]

    rows: list[tuple[str, float, str]] = []
    env = os.environ.get("RAYON_NUM_THREADS")
    print(f"threads: {_rgbd_rs.num_threads()} (RAYON_NUM_THREADS={env})")
    print(f"mesh: Stanford bunny subdivided, {len(mesh.triangles)} faces")
    peer = peers(mesh.vertices, mesh.triangles)
    for res in (320, 64):
        ours = timeit(
            lambda res=res: _rgbd_rs.mesh_depth_views(mesh.vertices, mesh.triangles, res), REPEATS
        )
        rc = timeit(
            lambda res=res: _rgbd_rs.mesh_depth_views_raycast(mesh.vertices, mesh.triangles, res),
            REPEATS,
        )
        full = timeit(lambda res=res: depth_views(mesh, res), REPEATS)
        rows.append((f"6 views {res}x{res}, mesh: rgbd_rs rasterizer (raw)", ours, ""))
        rows.append((f"6 views {res}x{res}, mesh: rgbd_rs BVH ray casting (raw)", rc, ""))
        rows.append((f"6 views {res}x{res}, mesh: depth_views (+ LCN)", full, ""))
        o, d = rays(mesh.vertices, res)
        for name, (build, cast) in peer.items():
            built = build()
            t_cast = timeit(lambda cast=cast, built=built, o=o, d=d: cast(built, o, d), REPEATS)
            t_all = timeit(lambda cast=cast, build=build, o=o, d=d: cast(build(), o, d), REPEATS)
            rows.append(
                (f"6 views {res}x{res}, mesh: {name} cast only", t_cast, f"{t_cast / ours:.1f}x")
            )
            rows.append(
                (f"6 views {res}x{res}, mesh: {name} build + cast", t_all, f"{t_all / ours:.1f}x")
            )
    for res in (64, 320):
        one = timeit(lambda res=res: depth_views(clouds[0], res, lcn=False), REPEATS)
        rows.append((f"6 views {res}x{res}, 1024 ModelNet points (raw)", one, ""))
    loop = timeit(lambda: [depth_views(c, 64) for c in clouds], 3)
    batch = timeit(lambda: depth_views_batch(clouds, 64), 3)
    rows.append(("64 clouds x 6 views 64x64 + LCN: loop of depth_views", loop, ""))
    rows.append(
        ("64 clouds x 6 views 64x64 + LCN: depth_views_batch", batch, f"{loop / batch:.1f}x")
    )
    for res in (64, 320):
        img = np.random.default_rng(0).random((6, res, res)).astype(np.float32)
        w = lcn_window(res)
        t = timeit(lambda img=img, w=w: local_contrast_normalize(img, w), REPEATS)
        rows.append((f"LCN of 6 views {res}x{res}", t, ""))

    if args.markdown:
        print("| case | ms | rgbd_rs faster by |\n|---|---:|---:|")
        for name, ms, ratio in rows:
            print(f"| {name} | {ms:.2f} | {ratio} |")
    else:
        for name, ms, ratio in rows:
            print(f"{name:<66} {ms:9.2f} ms  {ratio}")


if __name__ == "__main__":
    main()
