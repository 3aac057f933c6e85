"""Legal mesh files the readers used to misread: OFF comments, per-face colours and header
variants (rgbd_rs.meshes.load_mesh), and OBJ relative (negative) indices, which trimesh resolves
against the file's last vertex instead of the line's (rgbd_rs.shapes.load_shape)."""

from __future__ import annotations

from pathlib import Path
from typing import Any

import numpy as np
import pytest
import trimesh

import rgbd_rs.shapes.dataset as D
from rgbd_rs.errors import RgbdError
from rgbd_rs.meshes import Mesh, load_mesh
from rgbd_rs.shapes import load_shape

#: A unit tetrahedron's corners, one per line, and its four faces.
TETRA = "0 0 0\n1 0 0\n0 1 0\n0 0 1\n"
TETRA_V = [[0, 0, 0], [1, 0, 0], [0, 1, 0], [0, 0, 1]]
TETRA_F = [[0, 2, 1], [0, 1, 3], [0, 3, 2], [1, 2, 3]]


def _mesh(path: Path, text: str) -> Mesh:
    path.write_text(text)
    mesh = load_mesh(path)
    assert isinstance(mesh, Mesh)
    return mesh


def _obj(path: Path, text: str) -> Mesh:
    path.write_text(text)
    mesh = load_shape(path)
    assert isinstance(mesh, Mesh)
    return mesh


# -- OFF ---------------------------------------------------------------------------------------


def test_off_comments_run_to_the_end_of_their_line(tmp_path: Path) -> None:
    # The whole file after the first '#' used to be dropped: "header says 4 vertices, found 0".
    text = (
        "# made by hand\nOFF\n# counts next\n4 4 0\n\n0 0 0  # the origin\n1 0 0\n0 1 0\n0 0 1\n"
        "# faces\n3 0 2 1\n3 0 1 3 # the floor\n3 0 3 2\n3 1 2 3\n# end\n"
    )
    mesh = _mesh(tmp_path / "comments.off", text)
    assert mesh.vertices.tolist() == TETRA_V and mesh.triangles.tolist() == TETRA_F


@pytest.mark.parametrize(
    "colours",
    [["255 0 0"] * 4, ["0.5 0.5 0.5 1"] * 4, ["255 0 0", "", "1", "0 0 255 128"]],
    ids=["rgb bytes", "rgba floats", "mixed"],
)
def test_off_face_colours_are_ignored(tmp_path: Path, colours: list[str]) -> None:
    # A colour used to be read as the next face's vertex count: faces lost or "truncated file".
    faces = "".join(
        f"3 {' '.join(map(str, f))} {c}\n" for f, c in zip(TETRA_F, colours, strict=True)
    )
    mesh = _mesh(tmp_path / "colours.off", f"COFF\n4 4 0\n{TETRA}{faces}")
    assert mesh.triangles.tolist() == TETRA_F


def test_off_faces_of_several_sizes_keep_their_order_and_colours(tmp_path: Path) -> None:
    text = "OFF\n5 3 0\n0 0 0\n1 0 0\n1 1 0\n0 1 0\n0 0 1\n4 0 1 2 3 9 9 9\n3 0 1 4 7\n3 1 2 4\n"
    mesh = _mesh(tmp_path / "mixed.off", text)
    assert mesh.triangles.tolist() == [[0, 1, 2], [0, 2, 3], [0, 1, 4], [1, 2, 4]]


@pytest.mark.parametrize(
    ("keyword", "extra"),
    [
        ("COFF", " 255 0 0 255"),
        ("NOFF", " 0 0 1"),
        ("CNOFF", " 0 0 1 0.1 0.2 0.3 1"),
        ("STOFF", " 0.5 0.5"),
        ("STCNOFF", " 0 0 1 1 1 1 1 0.5 0.5"),
    ],
)
def test_off_header_variants_use_three_values_per_vertex(
    tmp_path: Path, keyword: str, extra: str
) -> None:
    # These headers were refused: "no OFF header".
    vertices = "".join(f"{row}{extra}\n" for row in TETRA.splitlines())
    faces = "".join(f"3 {' '.join(map(str, f))}\n" for f in TETRA_F)
    mesh = _mesh(tmp_path / "variant.off", f"{keyword}\n4 4 0\n{vertices}{faces}")
    assert mesh.vertices.tolist() == TETRA_V and mesh.triangles.tolist() == TETRA_F


@pytest.mark.parametrize(
    "head", ["OFF3 1 0\n", "OFF 3 1 0\n", "OFF\n3 1\n", "OFF\n\n3 1 0\n"], ids=repr
)
def test_off_counts_fused_on_the_header_line_or_without_edges(tmp_path: Path, head: str) -> None:
    mesh = _mesh(tmp_path / "head.off", f"{head}0 0 0\n1 0 0\n0 1 0\n3 0 1 2\n")
    assert mesh.triangles.tolist() == [[0, 1, 2]]


@pytest.mark.parametrize(
    ("text", "match"),
    [
        ("4OFF\n3 1 0\n0 0 0 1\n1 0 0 1\n0 1 0 1\n3 0 1 2\n", r"'4OFF' declares 4-D vertices"),
        ("nOFF\n4\n3 1 0\n", r"'nOFF' declares n-D vertices"),
        ("OFF BINARY\n", r"a binary OFF file, which is not supported"),
        ("PLY\n3 1 0\n", r"no OFF header: it begins 'PLY', expected OFF, COFF"),
        ("OFF\n3 1 0\n0 0\n1 0 0\n0 1 0\n3 0 1 2\n", r"vertex 0 \('0 0'\) has 2 values"),
        ("OFF\n3 2 0\n0 0 0\n1 0 0\n0 1 0\n3 0 1\n3 0 1 2\n", r"face 0 \('3 0 1'\) lists 2"),
        ("OFF\n3 2 0\n0 0 0\n1 0 0\n0 1 0\n4 0 1 2 0\n3 0 1 7 1\n", r"face 1 has vertex index 7"),
        ("OFF\n3 1 0\n0 0 0\n1 0 0\n0 1 0\n# 3 0 1 2\n", r"header says 1 faces, found 0"),
    ],
    ids=[
        "4-D",
        "n-D",
        "binary",
        "not OFF",
        "short vertex",
        "short face",
        "index, mixed sizes",
        "face commented out",
    ],
)
def test_off_refusals_say_what_is_wrong(tmp_path: Path, text: str, match: str) -> None:
    path = tmp_path / "bad.off"
    path.write_text(text)
    with pytest.raises(RgbdError, match=rf"bad\.off: not a valid OFF mesh \(.*{match}"):
        load_mesh(path)


def test_off_real_meshes_read_as_trimesh_reads_them(shared_data: Path) -> None:
    for name in ("stanford_bunny.off", "modelnet40_bed_0001.off"):
        path = shared_data / "meshes" / name
        mesh, ref = load_mesh(path), trimesh.load_mesh(path, process=False)
        np.testing.assert_array_equal(mesh.triangles, ref.faces)
        np.testing.assert_allclose(mesh.vertices, ref.vertices, rtol=1e-6)


# -- OBJ ---------------------------------------------------------------------------------------

TWO_OBJECTS = (
    "o a\nv 0 0 0\nv 1 0 0\nv 0 1 0\nf -3 -2 -1\no b\nv 0 0 5\nv 1 0 5\nv 0 1 5\nf -3 -2 -1\n"
)


def test_obj_relative_indices_count_back_from_their_line(tmp_path: Path) -> None:
    # trimesh alone put both triangles on the second object's vertices (at z = 5).
    mesh = _obj(tmp_path / "two.obj", TWO_OBJECTS)
    assert mesh.triangles.tolist() == [[0, 1, 2], [3, 4, 5]]
    assert mesh.vertices[mesh.triangles][:, :, 2].tolist() == [[0, 0, 0], [5, 5, 5]]


def test_obj_relative_texture_and_normal_indices(tmp_path: Path) -> None:
    head = "v 0 0 0\nv 1 0 0\nv 0 1 0\nvt 0 0\nvt 1 0\nvt 0 1\nvn 0 0 1\n"
    tail = "v 0 0 5\nv 1 0 5\nv 0 1 5\nv 1 1 5\nvn 0 0 -1\n"
    rel = f"{head}f -3/-3/-1 -2/-2/-1 -1/-1/-1\n{tail}f -4//-1 -3//-1 -1//-1\nl -7 -1\n"
    absolute = f"{head}f 1/1/1 2/2/1 3/3/1\n{tail}f 4//2 5//2 7//2\nl 1 7\n"
    assert D._obj_absolute(tmp_path / "x.obj", rel.encode()) == absolute.encode()
    got, want = _obj(tmp_path / "rel.obj", rel), _obj(tmp_path / "abs.obj", absolute)
    np.testing.assert_array_equal(got.vertices, want.vertices)
    np.testing.assert_array_equal(got.triangles, want.triangles)
    assert len(got.triangles) == 2


def test_obj_relative_indices_keep_materials(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    # Read from memory, the rewritten file still finds its material library beside it.
    (tmp_path / "m.mtl").write_text("newmtl red\nKd 1 0 0\nnewmtl blue\nKd 0 0 1\n")
    body = "mtllib m.mtl\nusemtl red\n" + TWO_OBJECTS.replace("o b\n", "o b\nusemtl blue\n")
    loaded: list[Any] = []
    load = trimesh.load

    def spy(*args: Any, **kwargs: Any) -> Any:
        loaded.append(load(*args, **kwargs))
        return loaded[-1]

    monkeypatch.setattr(trimesh, "load", spy)
    got = _obj(tmp_path / "rel.obj", body)
    assert sorted(got.vertices[got.triangles][:, :, 2].tolist()) == [[0, 0, 0], [5, 5, 5]]
    colours = [g.visual.material.diffuse.tolist() for g in loaded[0].geometry.values()]
    assert sorted(colours) == [[0, 0, 255, 255], [255, 0, 0, 255]]


def test_obj_without_relative_indices_is_not_rewritten(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    def fail(p: Path, data: bytes) -> bytes:
        raise AssertionError("rewrote a file without relative indices")

    monkeypatch.setattr(D, "_obj_absolute", fail)
    mesh = _obj(tmp_path / "plain.obj", "v 0 0 0\nv 1 0 0\nv 0 -1 0\n# f -1 0 2\nf 1 2 3\n")
    assert mesh.triangles.tolist() == [[0, 1, 2]]


@pytest.mark.parametrize(
    ("face", "match"),
    [
        ("f 0 1 2", r"vertex index 0, expected 1\.\.3 or -1\.\.-3"),
        ("f -4 -2 -1", r"vertex index -4, expected 1\.\.3 or -1\.\.-3"),
        ("f 1/-1 2/-1 3/-1", r"texture coordinate index -1, expected a texture coordinate"),
        ("f 1//0 2//1 3//1", r"normal index 0, expected a normal defined above it, found none"),
        ("l -1 0", r"vertex index 0"),
    ],
    ids=["zero", "before the first", "texture", "normal", "line"],
)
def test_obj_zero_or_too_far_back_indices_are_refused(
    tmp_path: Path, face: str, match: str
) -> None:
    # trimesh read "f 0 1 2" as a triangle on vertices 0, 0, 1 without a word.
    path = tmp_path / "bad.obj"
    path.write_text(f"v 0 0 0\nv 1 0 0\nv 0 1 0\n{face}\nf 1 2 3\n")
    with pytest.raises(RgbdError, match=rf"bad\.obj: not a valid OBJ file \(line 4, '{face}': "):
        load_shape(path)
    with pytest.raises(RgbdError, match=match):
        load_shape(path)


@pytest.mark.parametrize(
    "text",
    [
        "OFF 3 1 0 0 0 0 1 0 0 0 1 0 3 0 1 2\n",  # all on one line
        "OFF\n3 1 0\n0 0 0 1 0 0\n0 1 0\n3 0 1 2\n",  # two vertices on a line
        "OFF\n3 1 0\n0 0 0\n1 0 0\n0 1 0\n3 0 1\n2\n",  # a face wrapped
        "OFF3\n1 0\n0 0 0\n1 0 0\n0 1 0\n3 0 1 2  # counts split\n",
    ],
    ids=["one line", "two vertices a line", "face wrapped", "counts split"],
)
def test_off_free_format_still_loads(tmp_path: Path, text: str) -> None:
    """A review: the format allows line breaks anywhere but inside a face's colour, and the
    former stream reader loaded these; the line-wise reading falls back to it."""
    assert _mesh(tmp_path / "free.off", text).triangles.tolist() == [[0, 1, 2]]
