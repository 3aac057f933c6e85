"""Voxelization speed: rgbd_rs.shapes.voxelize against trimesh's `voxelized` and Open3D's
`VoxelGrid.create_from_triangle_mesh`, in the same run (issue 14: ~190 ms / 4-7 ms at 32^3 for a
16k-face mesh here). All three mark the voxels the surface touches; rgbd_rs also times the solid
fill and the three density profiles. Medians after a warm-up.

    python benches/bench_voxels.py
"""

from __future__ import annotations

import numpy as np

from _timing import timeit
from rgbd_rs.data.paths import data_root
from rgbd_rs.meshes import load_mesh
from rgbd_rs.shapes import density_profiles, voxelize

REPEATS = 7


def main() -> None:
    import trimesh

    root = data_root(required=True)
    mesh = load_mesh(root / "meshes" / "pyvista_airplane.ply")
    tm = trimesh.Trimesh(mesh.vertices, mesh.triangles, process=False)
    # Subdivide to ~16k faces, the reference size.
    while len(tm.faces) < 16000:
        tm = tm.subdivide()
    from rgbd_rs.meshes import Mesh

    m = Mesh(tm.vertices.astype(np.float32), tm.faces.astype(np.uint32))
    print(f"mesh: {len(tm.faces)} faces")
    print(
        "| resolution | rgbd_rs surface | rgbd_rs solid + profiles | trimesh voxelized "
        "| Open3D VoxelGrid | vs trimesh | vs Open3D |"
    )
    print("|---|---|---|---|---|---|---|")
    try:
        import open3d as o3d

        o3m = o3d.geometry.TriangleMesh(
            o3d.utility.Vector3dVector(tm.vertices), o3d.utility.Vector3iVector(tm.faces)
        )
    except Exception:  # Open3D is optional (the bench extra)
        o3m = None
    for r in (32, 64, 128):
        ours = timeit(lambda: voxelize(m, r), REPEATS)  # noqa: B023
        solid = timeit(lambda: density_profiles(voxelize(m, r, fill="solid")), REPEATS)  # noqa: B023
        pitch = float(tm.extents.max()) / r
        tri = timeit(lambda: tm.voxelized(pitch=pitch), 3)  # noqa: B023
        if o3m is not None:
            o3 = timeit(
                lambda: o3d.geometry.VoxelGrid.create_from_triangle_mesh(o3m, pitch),  # noqa: B023
                REPEATS,
            )
            o3s, o3r = f"{o3:.1f} ms", f"{o3 / ours:.1f}x"
        else:
            o3s = o3r = "unavailable"
        print(
            f"| {r}^3 | {ours:.1f} ms | {solid:.1f} ms | {tri:.1f} ms | {o3s} "
            f"| {tri / ours:.0f}x | {o3r} |"
        )


if __name__ == "__main__":
    main()
