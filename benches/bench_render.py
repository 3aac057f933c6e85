"""Ray-casting speed: rgbd_rs.render against trimesh (Embree backend via embreex) and Open3D's
RaycastingScene (Embree 4), for the same first-hit rays (960x540, one per pixel) in the same run,
on two cases:

- scene: the synthetic dataset's cluttered room (shared meshes + a tessellated sphere, ~100k
  triangles), seen by the rig's right camera;
- dense mesh: the Stanford bunny of ../shared/data/meshes (3674 triangles) midpoint-subdivided
  three times (235,136 triangles; flat subdivision, the shape is unchanged), 1 m across at 1.4 m,
  filling the image height (about a third of the rays hit it).

Plus seconds per synthetic dataset scene (960x540 stereo pair with 2x2 supersampling + 512x424
ToF frame with 2x2 sub-samples and 8 multipath rays).

The peers get precomputed ray arrays (their ray generation is not timed); rgbd_rs generates its
rays inside the call. "vs X" = X's time / rgbd_rs's time (> 1: rgbd_rs is faster); wall time is
the median of 5 runs, CPU time (all threads of the process) the least of 5, which other jobs on
the same cores inflate much less. Peers that cannot be imported are reported as unavailable.
Threads: RAYON_NUM_THREADS if set (Open3D gets the same count), else all cores.

    python benches/bench_render.py             # table on stdout
    python benches/bench_render.py --markdown  # the README table
    RAYON_NUM_THREADS=1 python benches/bench_render.py --no-scene  # one thread, casting only
"""

from __future__ import annotations

import argparse
import os
import time
from collections.abc import Callable

import numpy as np

from _timing import timeit
from rgbd_rs import PinholeCamera
from rgbd_rs.render import RenderScene

REPEATS = 5

#: (name, wall ms, CPU ms, median |z - ours|) of one ray caster on one case.
Row = tuple[str, float, float, float]
NAN_ROW = (float("nan"), float("nan"), float("nan"))


def timed(fn: Callable[[], object]) -> tuple[float, float]:
    """Median wall time (``_timing.timeit``) and the least CPU time of the process (all its
    threads; unlike wall time, not inflated when other jobs share the cores), in ms."""
    wall = timeit(fn, REPEATS)
    cpu = []
    for _ in range(REPEATS):
        t = time.process_time()
        fn()
        cpu.append(time.process_time() - t)
    return wall, min(cpu) * 1e3


def scene_and_rays():  # type: ignore[no-untyped-def]
    from rgbd_rs.data.synth import synth3_rig
    from rgbd_rs.data.synth_scene import _random_scene, _shared_meshes
    from rgbd_rs.meshes import sphere

    rng = np.random.default_rng(0)
    sc = _random_scene(rng, _shared_meshes())
    n_tris = sum(len(m.triangles) for m, _ in sc.objects)
    # Top up to ~100k triangles with a finely tessellated sphere in view.
    rings = int(np.sqrt(max(100_000 - n_tris, 0) / 2))
    sc.add(sphere(0.4, center=(0.3, 0.2, 2.5), rings=rings, segments=rings))
    built = sc.build()
    rig = synth3_rig(0.5)
    cam = rig.stereo.right
    v, u = np.mgrid[0 : cam.height, 0 : cam.width].astype(np.float64)
    d = np.stack([(u - cam.cx) / cam.fx, (v - cam.cy) / cam.fy, np.ones_like(u)], -1).reshape(-1, 3)
    verts = np.concatenate([m.vertices for m, _ in sc.objects])
    offs = np.cumsum([0] + [len(m.vertices) for m, _ in sc.objects[:-1]])
    faces = np.concatenate(
        [m.triangles.astype(np.int64) + o for (m, _), o in zip(sc.objects, offs, strict=True)]
    )
    return sc, built, rig, d, verts, faces


def subdivide(v: np.ndarray, f: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Midpoint subdivision: every triangle into four (shared edge midpoints)."""
    e = np.sort(np.concatenate([f[:, [0, 1]], f[:, [1, 2]], f[:, [2, 0]]]), axis=1)
    uniq, inv = np.unique(e, axis=0, return_inverse=True)
    mid = (v[uniq[:, 0]] + v[uniq[:, 1]]) / 2
    ab, bc, ca = inv.reshape(3, -1) + len(v)
    a, b, c = f.T
    quads = ((a, ab, ca), (ab, b, bc), (ca, bc, c), (ab, bc, ca))
    return np.concatenate([v, mid]), np.concatenate([np.stack(t, 1) for t in quads])


def dense_mesh() -> tuple[np.ndarray, np.ndarray]:
    """The bunny subdivided to 235k triangles, 1 m across, 1.4 m in front of the camera."""
    from rgbd_rs.data.paths import data_root
    from rgbd_rs.meshes import load_mesh

    root = data_root(required=True)
    assert root is not None
    m = load_mesh(root / "meshes" / "stanford_bunny.off").normalized(1.0)
    v, f = m.vertices.astype(np.float64), m.triangles.astype(np.int64)
    for _ in range(3):
        v, f = subdivide(v, f)
    # y up -> y down (camera frame), facing the camera.
    return v * [1.0, -1.0, -1.0] + [0.0, 0.0, 1.4], f


def cast_all(
    built: RenderScene,
    cam: PinholeCamera,
    d: np.ndarray,
    verts: np.ndarray,
    faces: np.ndarray,
    threads: int,
) -> list[Row]:
    """A row for rgbd_rs and each peer on the same rays."""
    from rgbd_rs import Pose

    ours_depth = built.depth(cam, Pose.identity())
    rows: list[Row] = [
        (
            "rgbd_rs (8-wide BVH, 8-ray packets, rayon)",
            *timed(lambda: built.depth(cam, Pose.identity())),
            0.0,
        )
    ]
    n_rays = len(d)

    try:
        import trimesh
        from trimesh.ray.ray_pyembree import RayMeshIntersector

        mesh = trimesh.Trimesh(verts, faces, process=False)
        inter = RayMeshIntersector(mesh)
        origins = np.zeros_like(d)
        dn = d / np.linalg.norm(d, axis=1, keepdims=True)

        def tri_cast() -> tuple[np.ndarray, np.ndarray]:
            return inter.intersects_location(origins, dn, multiple_hits=False)[:2]

        loc, idx = tri_cast()
        z = np.full(n_rays, np.nan)
        z[idx] = loc[:, 2]
        diff = np.nanmedian(np.abs(z - ours_depth.ravel()))
        rows.append((f"trimesh {trimesh.__version__} + embreex", *timed(tri_cast), diff))
    except ImportError as exc:
        rows.append((f"trimesh+embree unavailable ({exc.name})", *NAN_ROW))

    try:
        import open3d as o3d

        rs = o3d.t.geometry.RaycastingScene()
        rs.add_triangles(
            o3d.core.Tensor(verts.astype(np.float32)), o3d.core.Tensor(faces.astype(np.uint32))
        )
        rays = o3d.core.Tensor(np.concatenate([np.zeros_like(d), d], 1).astype(np.float32))

        def o3d_cast() -> np.ndarray:
            return rs.cast_rays(rays, nthreads=threads)["t_hit"].numpy()

        z = o3d_cast()  # t along the z=1 direction = depth
        z = np.where(np.isfinite(z), z, np.nan)
        diff = np.nanmedian(np.abs(z - ours_depth.ravel()))
        rows.append((f"Open3D {o3d.__version__} RaycastingScene", *timed(o3d_cast), diff))
    except ImportError as exc:
        rows.append((f"Open3D unavailable ({exc})", *NAN_ROW))
    return rows


def main() -> None:
    ap = argparse.ArgumentParser(
        description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter
    )
    ap.add_argument("--markdown", action="store_true")
    ap.add_argument(
        "--no-scene", action="store_true", help="skip the synthetic-scene (stereo + ToF) timing"
    )
    args = ap.parse_args()

    from rgbd_rs.data.synth import _rig_poses
    from rgbd_rs.render import Scene, ToFModel

    threads = int(os.environ.get("RAYON_NUM_THREADS", os.cpu_count() or 1))
    _, built, rig, d, verts, faces = scene_and_rays()
    cam = rig.stereo.right
    dv, df = dense_mesh()
    from rgbd_rs.meshes import Mesh

    dense = Scene().add(Mesh(dv.astype(np.float32), df.astype(np.uint32))).build()
    cases = [
        (
            f"scene: {built.triangle_count} triangles",
            cast_all(built, cam, d, verts, faces, threads),
        ),
        (
            f"dense mesh (bunny subdivided): {dense.triangle_count} triangles",
            cast_all(dense, cam, d, dv, df, threads),
        ),
    ]
    n_rays = len(d)
    head = f"first-hit depth, {cam.width}x{cam.height} rays, {threads} threads"
    if args.markdown:
        print(f"| {head} | ms | Mrays/s | vs it | CPU ms | vs it (CPU) | median abs z diff |")
        print("|---|---|---|---|---|---|---|")
        for case, rows in cases:
            print(f"| **{case}** | | | | | | |")
            _, t_ours, c_ours, _ = rows[0]
            for name, t, c, diff in rows:
                print(
                    f"| {name} | {t:.1f} | {n_rays / t / 1e3:.2f} | {t / t_ours:.2f}x "
                    f"| {c:.1f} | {c / c_ours:.2f}x | {diff:.1e} m |"
                )
    else:
        print(head)
        for case, rows in cases:
            print(f" {case}")
            _, t_ours, c_ours, _ = rows[0]
            for name, t, c, diff in rows:
                print(
                    f"  {name:45s} {t:8.1f} ms  {n_rays / t / 1e3:6.2f} Mrays/s  "
                    f"vs it {t / t_ours:5.2f}x  CPU {c:7.1f} ms ({c / c_ours:5.2f}x)  "
                    f"|dz| {diff:.1e}"
                )
    if args.no_scene:
        return
    to_left, to_right, to_tof = _rig_poses(rig)
    model = ToFModel(subsamples=2, multipath_rays=8)

    def full_scene() -> None:
        built.color(rig.stereo.left, to_left, supersample=2)
        built.color(rig.stereo.right, to_right, supersample=2)
        built.tof(rig.tof, to_tof, model)

    t_scene = timeit(full_scene, 3)
    t_tof = timeit(lambda: built.tof(rig.tof, to_tof, model), 3)
    print(
        f"\nSynthetic scene (stereo pair 2x2 SS + ToF 2x2 sub-samples, 8 multipath rays): "
        f"{t_scene / 1e3:.2f} s, of which ToF {t_tof / 1e3:.2f} s"
    )


if __name__ == "__main__":
    main()
