"""Bad input to :mod:`rgbd_rs.render`, :mod:`rgbd_rs.surface` and :mod:`rgbd_rs.meshes` (see
tests/test_bad_input.py for the contract and the meta-test that counts these cases).

Sizes that would allocate terabytes run in a child interpreter (``isolated``): a missing check
aborts the child, not the test run."""

from __future__ import annotations

import subprocess
import sys
import textwrap
from pathlib import Path

import numpy as np
import pytest

from bad_input import Case, check, isolated, params
from rgbd_rs import InvalidArgumentError, PinholeCamera, RgbdError, ShapeMismatchError
from rgbd_rs.meshes import Mesh, box, concat, cylinder, load_mesh, quad, sphere
from rgbd_rs.render import (
    Material,
    OrthographicCamera,
    PointLight,
    Scene,
    Texture,
    ToFModel,
    render_points,
)
from rgbd_rs.surface import SegmentFits, fit_grid, fit_mask, ortho_points

SHAPE = ShapeMismatchError
ARG = InvalidArgumentError

BOX = box((1.0, 1.0, 1.0), center=(0.0, 0.0, 3.0))
SCENE = Scene().add(BOX).build()
CAM = PinholeCamera(20.0, 20.0, 7.5, 5.5, 16, 12)
ORTHO = OrthographicCamera(10.0, 16, 12)
POINTS = np.random.default_rng(0).normal(3.0, 0.1, size=(12, 16, 3)).astype(np.float32)
LABELS = np.repeat(np.arange(4), 48).reshape(12, 16)
FITS = SegmentFits(POINTS, LABELS)


def _mesh_file(tmp: Path, name: str, text: str) -> Path:
    p = tmp / name
    p.write_text(text)
    return p


CASES: list[Case] = [
    # -- render ---------------------------------------------------------------------------------
    Case("Texture.checker", lambda: Texture.checker(0.0), ARG, r"^period: got 0"),
    Case("Texture.stripes", lambda: Texture.stripes(1.0, angle="x"), ARG, r"^angle: got 'x'"),
    Case("Texture.noise", lambda: Texture.noise(1.0, seed=-1), ARG, r"^seed: got -1"),
    Case("Texture.image", lambda: Texture.image(np.zeros((4, 4)), 1.0), SHAPE, r"^rgb: got shape"),
    Case(
        "Texture",
        lambda: Scene().add(BOX, Material(texture=Texture("checker", ("x",)))).build(),
        ARG,
        r"^(texture|params|period)",
    ),
    Case(
        "Material",
        lambda: Scene().add(BOX, Material(albedo_ir="x")).build(),
        ARG,
        r"^albedo_ir: got 'x'",
    ),
    Case(
        "Material",
        lambda: Scene().add(BOX, Material(albedo=(1.0, 2.0))).build(),
        ARG,
        r"^albedo: got",
        "albedo",
    ),
    Case(
        "PointLight",
        lambda: Scene(lights=[PointLight(position="x")]).add(BOX).build(),
        ARG,
        r"^position: got",
    ),
    Case("OrthographicCamera", lambda: OrthographicCamera(0.0, 4, 4), ARG, r"^scale: got 0"),
    Case(
        "OrthographicCamera",
        isolated(
            "from rgbd_rs.render import OrthographicCamera, Scene\n"
            "Scene().build().depth(OrthographicCamera(1.0, np.uint64(2**64 - 1), 1))"
        ),
        ARG,
        r"^width",
        "uint64 width",
    ),
    Case(
        "ToFModel",
        lambda: SCENE.tof(CAM, None, ToFModel(frequency_hz=0.0)),
        ARG,
        r"^frequency_hz: got 0",
    ),
    Case(
        "ToFModel",
        lambda: SCENE.tof(CAM, None, ToFModel(power="x")),
        ARG,
        r"^power: got 'x'",
        "power",
    ),
    Case("ToFModel.only", lambda: ToFModel().only("rain"), ARG, r"^effect: got 'rain'"),
    Case("Scene", lambda: Scene(ambient="x").build(), ARG, r"^ambient: got 'x'"),
    Case("Scene.add", lambda: Scene().add("mesh"), ARG, r"^mesh: got str"),
    Case(
        "Scene.add",
        lambda: Scene().add(BOX, material="red").build(),
        ARG,
        r"^material: got str",
        "material",
    ),
    Case(
        "Scene.build",
        lambda: Scene(objects=[(BOX, "red")]).build(),
        ARG,
        r"^(objects|material)",
    ),
    Case("RenderScene.depth", lambda: SCENE.depth("cam"), ARG, r"^camera: got str"),
    Case(
        "RenderScene.depth",
        isolated(
            "from rgbd_rs.render import OrthographicCamera, Scene\n"
            "Scene().build().depth(OrthographicCamera(1.0, 2**20, 2**20))"
        ),
        ARG,
        r"width|height|pixels",
        "2**20 x 2**20 orthographic",
    ),
    Case(
        "RenderScene.depth",
        isolated(
            "from rgbd_rs.render import Scene\n"
            "Scene().build().depth(rgbd_rs.PinholeCamera(1.0, 1.0, 0.0, 0.0, 2**20, 2**20))"
        ),
        ARG,
        r"width|height|pixels",
        "2**20 x 2**20 pinhole",
    ),
    Case(
        "RenderScene.gbuffer",
        lambda: SCENE.gbuffer(CAM, pose="x"),
        ARG,
        r"^pose: got str",
    ),
    Case(
        "RenderScene.color",
        lambda: SCENE.color(CAM, supersample=0),
        ARG,
        r"^supersample: got 0",
    ),
    Case("RenderScene.tof", lambda: SCENE.tof(ORTHO), ARG, r"^camera: got OrthographicCamera"),
    Case(
        "RenderScene.tof",
        lambda: SCENE.tof(CAM, seed=-1),
        ARG,
        r"^seed: got -1",
        "seed",
    ),
    Case(
        "render_points",
        lambda: render_points(np.zeros((4, 2)), CAM, radius=0.1),
        SHAPE,
        r"^points: got shape \(4, 2\)",
    ),
    Case(
        "render_points",
        lambda: render_points(np.zeros((4, 3)), CAM, radius=0.0),
        ARG,
        r"^radius: got 0",
        "radius",
    ),
    Case(
        "render_points",
        isolated(
            "from rgbd_rs.render import OrthographicCamera, render_points\n"
            "render_points(np.zeros((1, 3)), OrthographicCamera(1.0, 2**20, 2**20), radius=1.0)"
        ),
        ARG,
        r"width|height|pixels",
        "2**20 x 2**20",
    ),
    # -- surface --------------------------------------------------------------------------------
    Case(
        "fit_mask",
        lambda: fit_mask(POINTS, np.ones((12, 16), np.int32)),
        ARG,
        r"^mask: got dtype int32",
    ),
    Case(
        "fit_mask",
        lambda: fit_mask(POINTS, np.ones((12, 15), bool)),
        SHAPE,
        r"^mask: got shape \(12, 15\)",
        "mask shape",
    ),
    Case(
        "fit_mask",
        lambda: fit_mask(POINTS, np.zeros((12, 16), bool)),
        ARG,
        r"^mask",
        "empty mask",
    ),
    Case("fit_grid", lambda: fit_grid(POINTS[..., :2]), SHAPE, r"^points: got shape \(12, 16, 2\)"),
    Case("fit_grid", lambda: fit_grid(POINTS, spacing=0.5), ARG, r"^spacing: got 0.5", "spacing"),
    Case(
        "fit_grid",
        lambda: fit_grid(POINTS, spacing=1e30),
        ARG,
        r"^spacing: got 1e\+30, expected at most .* the grid's larger side",
        "huge spacing",
    ),
    Case(
        "fit_mask",
        lambda: fit_mask(np.zeros((40, 48, 3), np.float32), None, spacing=200.0),
        ARG,
        r"^spacing: got 200, expected at most 96 px \(2 times the grid's larger side, 48 px",
        "spacing beyond the grid",
    ),
    Case("fit_grid", lambda: fit_grid(POINTS, degree=9), ARG, r"^degree: got 9", "degree"),
    Case("fit_grid", lambda: fit_grid(POINTS, lam=-1.0), ARG, r"^lam: got -1", "lam"),
    Case("ortho_points", lambda: ortho_points(np.ones(4), 1.0), SHAPE, r"^depth: got shape \(4,\)"),
    Case(
        "ortho_points",
        lambda: ortho_points(np.ones((4, 4)), 0.0),
        ARG,
        r"^pixel_size: got 0",
        "pixel size",
    ),
    Case(
        "SegmentFits",
        lambda: SegmentFits(POINTS, LABELS.astype(np.float32)),
        ARG,
        r"^labels: got dtype float32",
    ),
    Case(
        "SegmentFits",
        lambda: SegmentFits(POINTS[..., :2], LABELS),
        SHAPE,
        r"^points: got shape",
        "points",
    ),
    Case(
        "SegmentFits",
        lambda: SegmentFits(POINTS, LABELS[:, :-1]),
        SHAPE,
        r"^labels: got shape \(12, 15\)",
        "labels shape",
    ),
    Case(
        "SegmentFits",
        lambda: SegmentFits(POINTS, LABELS, criterion="aic"),
        ARG,
        r"^criterion: got 'aic'",
        "criterion",
    ),
    Case("SegmentFits.size", lambda: FITS.size(99), ARG, r"^i: got 99"),
    Case("SegmentFits.fit_error", lambda: FITS.fit_error(-1), ARG, r"^i: got -1"),
    Case("SegmentFits.mse", lambda: FITS.mse("a"), ARG, r"^i: got 'a'"),
    Case("SegmentFits.union_error", lambda: FITS.union_error(0, 99), ARG, r"^j: got 99"),
    Case("SegmentFits.should_merge", lambda: FITS.should_merge(99, 0), ARG, r"^i: got 99"),
    Case("SegmentFits.merge", lambda: FITS.merge(0, 99), ARG, r"^j: got 99"),
    Case("SegmentFits.seam", lambda: FITS.seam(0, 99), ARG, r"^j: got 99"),
    Case(
        "SegmentFits",
        lambda: SegmentFits(POINTS, LABELS, surfaces=False, criterion="gcv"),
        ARG,
        r"^surfaces: got False",
        "surfaces",
    ),
    Case(
        "SegmentFits",
        lambda: SegmentFits(POINTS, LABELS, test_spacing=0.5),
        ARG,
        r"^test_spacing: got 0.5",
        "test-spacing",
    ),
    Case(
        "SegmentFits",
        lambda: SegmentFits(POINTS, LABELS, test_spacing=1e30),
        ARG,
        r"^test_spacing: got 1e\+30, expected at most",
        "huge test-spacing",
    ),
    Case("SegmentFits.find", lambda: FITS.find(99), ARG, r"^label: got 99"),
    Case("SegmentFits.maps", lambda: FITS.maps(POINTS[:4]), SHAPE, r"^points: got shape \(4, 16"),
    # -- meshes ---------------------------------------------------------------------------------
    Case("Mesh", lambda: Mesh(np.zeros((3, 2)), np.zeros((1, 3))), SHAPE, r"^vertices: got shape"),
    Case(
        "Mesh",
        lambda: Mesh(np.zeros((3, 3), np.float32), np.array([[0, 1, 3]])),
        ARG,
        r"^triangles: got indices",
        "index",
    ),
    Case(
        "Mesh",
        lambda: Mesh(np.zeros((3, 3), np.float32), np.array([[0.0, 1.0, 2.0]])),
        ARG,
        r"^triangles: got float64",
        "float triangles",
    ),
    Case("Mesh.transformed", lambda: BOX.transformed("x"), ARG, r"^rotation: got dtype"),
    Case(
        "Mesh.transformed",
        lambda: BOX.transformed(translation=(1, 2)),
        SHAPE,
        r"^translation: got shape \(2,\)",
        "translation",
    ),
    Case("Mesh.scaled", lambda: BOX.scaled("x"), ARG, r"^factor: got 'x'"),
    Case("Mesh.scaled", lambda: BOX.scaled([[1, 2], [3]]), ARG, r"^factor: got", "ragged"),
    Case(
        "Mesh",
        lambda: Mesh(np.zeros((3, 3), np.float32), [[0, 1, 2], [0]]),
        ARG,
        r"^triangles: got list",
        "ragged",
    ),
    Case("Mesh.scaled", lambda: BOX.scaled((1.0, 2.0)), SHAPE, r"^factor: got shape", "2 axes"),
    Case("Mesh.normalized", lambda: BOX.normalized(0.0), ARG, r"^size: got 0"),
    Case("Mesh.merged", lambda: BOX.merged("x"), ARG, r"^others\[0\]: got str"),
    Case("concat", lambda: concat([BOX, None]), ARG, r"^meshes\[1\]: got NoneType"),
    Case("concat", lambda: concat(BOX), ARG, r"^meshes: got Mesh", "one mesh"),
    Case("quad", lambda: quad(np.zeros((3, 3))), SHAPE, r"^corners: got shape \(3, 3\)"),
    Case("box", lambda: box((1.0, 1.0)), SHAPE, r"^size: got shape \(2,\)"),
    Case("box", lambda: box((1.0, -1.0, 1.0)), ARG, r"^size: got", "negative"),
    Case("box", lambda: box((1.0, 1.0, 1.0), center="c"), ARG, r"^center: got 'c'", "center"),
    Case("cylinder", lambda: cylinder(1.0, 1.0, axis=3), ARG, r"^axis: got 3"),
    Case("cylinder", lambda: cylinder(0.0, 1.0), ARG, r"^radius: got 0", "radius"),
    Case("cylinder", lambda: cylinder(1.0, 1.0, segments=10**9), ARG, r"^segments", "huge"),
    Case("sphere", lambda: sphere(1.0, rings=1), ARG, r"^rings: got 1"),
    Case("sphere", lambda: sphere(1.0, center=(0, 0)), SHAPE, r"^center: got shape", "center"),
    Case("load_mesh", lambda: load_mesh(Path("/nonexistent/m.off")), ARG, r"^path: got"),
    Case("load_mesh", lambda: load_mesh(3), ARG, r"^path: got 3", "int"),
]


@pytest.mark.parametrize("case", params(CASES))
def test_bad_input(case: Case) -> None:
    check(case)


@pytest.mark.parametrize(
    ("text", "match"),
    [
        ("OFF\n3 1 0\n0 0 0\n1 0 0\n0 1 0\n3 0 1 -1\n", "vertex index -1"),
        ("OFF\n3 1 0\n0 0 0\n1 0 0\n0 1 0\n3 0 1 3\n", "vertex index 3"),
        ("OFF\n3 1 0\n0 0 0\n1 0 0\n0 1 0\n3 0 1\n", "ends inside face 0"),
        ("OFF\n3 1 0\n0 0 0\n1 0 0\n0 1\n", "header says 3 vertices, found 2"),
        ("OFF\n3 2 0\n0 0 0\n1 0 0\n0 1 0\n3 0 1 2\n", "header says 2 faces, found 1"),
        ("OFF\n3 1 0\n0 0 0\n1 0 0\n0 1 0\n3 0 1 x\n", "not a whole number"),
        ("OFF\n3 1 0\n0 0 0\n1 0 y\n0 1 0\n3 0 1 2\n", "vertex coordinate is not a number"),
        ("OFF\n3 1 0\n0 0 0\n1 0 0\n0 1 0\n-2 0 1 2\n", "negative vertex count"),
        ("OFF\n-3 1 0\n", "negative counts"),
        ("OFF\n", "no 'vertices faces edges' counts"),
        ("OFF\n3 1 0\n0 0 0\n1 0 0\n0 1 1e39\n3 0 1 2\n", "float32"),
        ("", "no OFF header"),
    ],
    ids=[
        "index -1",
        "index past the end",
        "truncated face",
        "truncated vertices",
        "missing face",
        "face index not a number",
        "coordinate not a number",
        "negative face size",
        "negative counts",
        "no counts",
        "beyond float32",
        "empty",
    ],
)
def test_bad_off_files_name_the_file(tmp_path: Path, text: str, match: str) -> None:
    path = _mesh_file(tmp_path, "bad.off", text)
    with pytest.raises(RgbdError, match=rf"bad\.off.*{match}") as info:
        load_mesh(path)
    assert type(info.value) is RgbdError


def test_a_label_near_2_31_is_compacted_not_allocated() -> None:
    """Issue 11: one label 2**31 - 2 aborted the interpreter (labels used as indices). Labels
    are compacted: the fit works, in a child interpreter so a regression cannot abort the run."""
    code = textwrap.dedent(
        """
        import numpy as np
        from rgbd_rs.surface import SegmentFits
        pts = np.random.default_rng(0).normal(3.0, 0.1, size=(8, 8, 3)).astype(np.float32)
        labels = np.zeros((8, 8), np.int64)
        labels[:4] = 2**31 - 2
        fits = SegmentFits(pts, labels)
        out = fits.labels()
        assert set(np.unique(out)) == {0, 2**31 - 2}, np.unique(out)
        assert fits.size(2**31 - 2) == 32 and fits.size(0) == 32
        print("ok")
        """
    )
    res = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=False)
    assert res.returncode == 0 and res.stdout.strip() == "ok", res.stderr[-2000:]
