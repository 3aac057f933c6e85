"""Ray-cast rendering on the Rust BVH (crates/rgbd-render): depth / normals / ids from
perspective or orthographic cameras, point-cloud splats, textured Lambertian colour images and a
continuous-wave ToF simulator (thesis §2.3, §3.5).

A :class:`Scene` lists meshes with materials, point lights and ambient light; :meth:`Scene.build`
builds the BVH once and returns a :class:`RenderScene` that renders from any camera. Poses are
world-to-camera (``X_c = R X_w + t``), as everywhere in rgbd_rs; depth is z in the camera frame.

Example:
    >>> import numpy as np
    >>> from rgbd_rs import PinholeCamera, Pose
    >>> from rgbd_rs.meshes import box
    >>> from rgbd_rs.render import Material, Scene
    >>> scene = Scene().add(box((4, 4, 0.1), center=(0, 0, 2.0)), Material()).build()
    >>> cam = PinholeCamera(50.0, 50.0, 31.5, 23.5, 64, 48)
    >>> round(float(np.nanmedian(scene.depth(cam, Pose.identity()))), 4)  # slab front face
    1.95
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Literal

import numpy as np
import numpy.typing as npt

from rgbd_rs import _rgbd_rs, _validate
from rgbd_rs._array_eq import array_eq
from rgbd_rs.camera import PinholeCamera, Pose, _pose_arg
from rgbd_rs.errors import InvalidArgumentError
from rgbd_rs.meshes import Mesh

F32 = npt.NDArray[np.float32]
I32 = npt.NDArray[np.int32]

TextureKind = Literal["uniform", "checker", "stripes", "noise", "image"]
__all__ = [
    "MAX_TOF_TERM",
    "GBuffer",
    "Material",
    "OrthographicCamera",
    "PointLight",
    "RenderScene",
    "Scene",
    "Texture",
    "ToFFrame",
    "ToFModel",
    "render_points",
]

_TEXTURE_KINDS = ("uniform", "checker", "stripes", "noise", "image")


def _reals(name: str, value: object, n: int) -> list[float]:
    """``n`` finite reals (a sequence), or an error naming ``name``."""
    if not isinstance(value, (tuple, list, np.ndarray)) or len(value) != n:
        raise InvalidArgumentError(f"{name}: got {value!r}, expected {n} numbers")
    return [_validate.real(f"{name}[{i}]", v) for i, v in enumerate(value)]


def _grey_or_rgb(name: str, value: object) -> list[float]:
    """A real (grey, used for all three channels) or three reals."""
    if isinstance(value, (int, float, np.integer, np.floating)) and not isinstance(value, bool):
        return [_validate.real(name, value)] * 3
    return _reals(name, value, 3)


@array_eq
@dataclass(frozen=True)
class Texture:
    """A texture in world units (tri-planar projection, no UVs needed).

    Use the constructors: :meth:`uniform`, :meth:`checker`, :meth:`stripes`, :meth:`noise`,
    :meth:`image`.
    """

    kind: TextureKind = "uniform"
    params: tuple[float, ...] = ()
    seed: int = 0
    image_rgb: F32 | None = None

    @classmethod
    def uniform(cls) -> Texture:
        """No texture (textureless: the weak spot of stereo)."""
        return cls()

    @classmethod
    def checker(cls, period: float) -> Texture:
        """Squares of side ``period`` metres."""
        return cls("checker", (_validate.real("period", period, positive=True, f32=True),))

    @classmethod
    def stripes(cls, period: float, angle: float = 0.0) -> Texture:
        """Sinusoidal stripes (repetitive, ambiguous for stereo): ``period`` m, ``angle`` rad."""
        return cls(
            "stripes",
            (
                _validate.real("period", period, positive=True, f32=True),
                _validate.real("angle", angle),
            ),
        )

    @classmethod
    def noise(cls, scale: float, seed: int = 0) -> Texture:
        """Multi-octave value noise with features of about ``scale`` metres."""
        s = _validate.integer("seed", seed, maximum=2**63 - 1)
        return cls("noise", (_validate.real("scale", scale, positive=True, f32=True),), s)

    @classmethod
    def image(cls, rgb: npt.ArrayLike, period: float) -> Texture:
        """An ``H x W x 3`` image (uint8 or float in [0, 1]) tiled every ``period`` metres."""
        arr = _validate.asarray("rgb", rgb)
        img = _validate.array("rgb", arr, shape=(None, None, 3), finite=True)
        if arr.dtype == np.uint8:
            img = img / np.float32(255)
        return cls("image", (_validate.real("period", period, positive=True, f32=True),), 0, img)

    def __post_init__(self) -> None:
        _validate.choice("kind", self.kind, _TEXTURE_KINDS)
        if not isinstance(self.params, (tuple, list)):
            raise InvalidArgumentError(f"params: got {self.params!r}, expected a tuple of numbers")
        for i, v in enumerate(self.params):
            _validate.real(f"params[{i}]", v)
        _validate.integer("seed", self.seed, maximum=2**63 - 1)
        if (self.kind == "image") != (self.image_rgb is not None) or (
            self.image_rgb is not None and not isinstance(self.image_rgb, np.ndarray)
        ):
            raise InvalidArgumentError(
                f"image_rgb: got {type(self.image_rgb).__name__} for texture {self.kind!r}, "
                "expected an image array exactly for 'image' (use Texture.image)"
            )

    def _native(self) -> tuple[str, list[float], int, F32 | None]:
        return self.kind, [float(p) for p in self.params], int(self.seed), self.image_rgb


@dataclass(frozen=True)
class Material:
    """Lambertian material: visible ``albedo`` (RGB in [0, 1]), near-IR ``albedo_ir`` (drives the
    ToF amplitude, untextured), a ``texture`` and its ``contrast`` (0 = texture invisible)."""

    albedo: tuple[float, float, float] = (0.7, 0.7, 0.7)
    albedo_ir: float = 0.5
    texture: Texture = field(default_factory=Texture)
    contrast: float = 0.8

    def __post_init__(self) -> None:
        _reals("albedo", self.albedo, 3)
        _validate.real("albedo_ir", self.albedo_ir)
        _validate.real("contrast", self.contrast)
        if not isinstance(self.texture, Texture):
            raise InvalidArgumentError(
                f"texture: got {type(self.texture).__name__}, expected a Texture"
            )

    def _native(self) -> tuple[list[float], float, float, str, list[float], int, F32 | None]:
        kind, params, seed, image = self.texture._native()
        albedo = [float(a) for a in self.albedo]
        return albedo, float(self.albedo_ir), float(self.contrast), kind, params, seed, image


@dataclass(frozen=True)
class PointLight:
    """Isotropic point light: ``intensity`` (RGB or grey) is the irradiance at 1 m."""

    position: tuple[float, float, float]
    intensity: float | tuple[float, float, float] = 1.0

    def __post_init__(self) -> None:
        _reals("position", self.position, 3)
        _grey_or_rgb("intensity", self.intensity)

    def _native(self) -> tuple[list[float], list[float]]:
        return _reals("position", self.position, 3), _grey_or_rgb("intensity", self.intensity)


@dataclass(frozen=True)
class OrthographicCamera:
    """Parallel projection: ``scale`` pixels per metre; ``cx``, ``cy`` default to the centre."""

    scale: float
    width: int
    height: int
    cx: float | None = None
    cy: float | None = None

    def __post_init__(self) -> None:
        _validate.real("scale", self.scale, positive=True)
        _validate.size("width", self.width)
        _validate.size("height", self.height)
        for name in ("cx", "cy"):
            if getattr(self, name) is not None:
                _validate.real(name, getattr(self, name))


#: Largest amplitude-unit term of a :class:`ToFModel`: the simulator computes in float32 and
#: squares the noise terms, which 1e15 squared (1e30) leaves finite. (A surface's amplitude also
#: grows as ``power / z**2``, so a large ``power`` over a surface centimetres away can still
#: overflow: the bound refuses absurd terms, it does not make every scene finite.)
MAX_TOF_TERM = 1e15


@dataclass(frozen=True)
class ToFModel:
    """Parameters of the ToF simulator (every effect can be switched off).

    Defaults: a Kinect-v2-like 120 MHz channel (SYNTH3's ``MHz120``), 2x2 sub-pixel rays (mixed
    pixels), 8 one-bounce multipath rays, noise with ``sigma^2 = read_noise^2 + shot_noise *
    (A + ambient)`` on I and Q, dropout below ``amplitude_threshold``, oracle phase unwrapping.
    ``power`` is the amplitude of an albedo-1 surface facing the camera at 1 m. The constants are
    chosen (the thesis gives none): an IR-albedo-0.5 wall has ~3 mm noise at 2 m and ~7 mm at 5 m;
    an albedo-0.03 object drops out (amplitude < 20) beyond ~5 m.
    """

    frequency_hz: float = 120e6
    subsamples: int = 2
    multipath_rays: int = 8
    noise: bool = True
    power: float = 20000.0
    read_noise: float = 2.0
    shot_noise: float = 0.4
    ambient: float = 10.0
    amplitude_threshold: float = 20.0
    wrap_phase: bool = False

    def __post_init__(self) -> None:
        # Checked when the model is made, not when a frame is rendered with it.
        _validate.real("frequency_hz", self.frequency_hz, positive=True)
        _validate.integer("subsamples", self.subsamples, minimum=1, maximum=8)
        _validate.integer("multipath_rays", self.multipath_rays, maximum=256)
        _validate.flag("noise", self.noise)
        _validate.real("power", self.power, positive=True)
        for name in ("read_noise", "shot_noise", "ambient", "amplitude_threshold"):
            _validate.real(name, getattr(self, name), nonnegative=True)
        for name in ("power", "read_noise", "shot_noise", "ambient", "amplitude_threshold"):
            if getattr(self, name) > MAX_TOF_TERM:
                raise InvalidArgumentError(
                    f"{name}: got {getattr(self, name):g}, expected at most {MAX_TOF_TERM:g} "
                    "(the simulator squares it in float32)"
                )
        _validate.flag("wrap_phase", self.wrap_phase)

    @classmethod
    def ideal(cls) -> ToFModel:
        """Every error source off: the sensor measures the true depth."""
        return cls(subsamples=1, multipath_rays=0, noise=False, amplitude_threshold=0.0)

    def only(self, effect: Literal["mixed", "multipath", "noise", "dropout"]) -> ToFModel:
        """This model with every error source but ``effect`` switched off."""
        _validate.choice("effect", effect, ("mixed", "multipath", "noise", "dropout"))
        ideal = ToFModel.ideal()
        return ToFModel(
            frequency_hz=self.frequency_hz,
            subsamples=self.subsamples if effect == "mixed" else 1,
            multipath_rays=self.multipath_rays if effect == "multipath" else 0,
            noise=self.noise and effect == "noise",
            power=self.power,
            read_noise=self.read_noise,
            shot_noise=self.shot_noise,
            ambient=self.ambient,
            amplitude_threshold=(
                self.amplitude_threshold if effect == "dropout" else ideal.amplitude_threshold
            ),
            wrap_phase=self.wrap_phase,
        )


@array_eq
@dataclass(frozen=True)
class ToFFrame:
    """A simulated ToF frame: measured ``depth`` (NaN = invalid), ``amplitude``, and the true
    depth through each pixel centre (``truth``)."""

    depth: F32
    amplitude: F32
    truth: F32


@array_eq
@dataclass(frozen=True)
class GBuffer:
    """First-hit attributes: depth, camera-frame normals (H x W x 3, facing the camera), triangle
    and object ids (-1 = miss) and barycentric coordinates (H x W x 2)."""

    depth: F32
    normal: F32
    triangle: I32
    object: I32
    barycentric: F32


Camera = PinholeCamera | OrthographicCamera


def _view(
    camera: Camera, pose: Pose | None
) -> tuple[str, float, float, float, float, int, int, tuple[list[float], list[float]]]:
    p = _pose_arg("pose", pose, default_identity=True)._native()
    if isinstance(camera, OrthographicCamera):
        cx = (camera.width - 1) / 2 if camera.cx is None else float(camera.cx)
        cy = (camera.height - 1) / 2 if camera.cy is None else float(camera.cy)
        s = float(camera.scale)
        return "orthographic", s, s, cx, cy, camera.width, camera.height, p
    if not isinstance(camera, PinholeCamera):
        raise InvalidArgumentError(
            f"camera: got {type(camera).__name__}, expected PinholeCamera or OrthographicCamera"
        )
    if not camera.distortion.is_identity:
        raise InvalidArgumentError(
            "camera: got a camera with lens distortion, expected an ideal pinhole "
            "(render with camera.without_distortion() and distort the image afterwards)"
        )
    return "perspective", camera.fx, camera.fy, camera.cx, camera.cy, camera.width, camera.height, p


@dataclass
class Scene:
    """Objects (mesh + material), point lights and ambient light; call :meth:`build` to render."""

    objects: list[tuple[Mesh, Material]] = field(default_factory=list)
    lights: list[PointLight] = field(default_factory=list)
    ambient: float | tuple[float, float, float] = 0.1

    def add(self, mesh: Mesh, material: Material | None = None) -> Scene:
        """Append an object; returns the scene for chaining."""
        if not isinstance(mesh, Mesh):
            raise InvalidArgumentError(f"mesh: got {type(mesh).__name__}, expected a Mesh")
        if material is not None and not isinstance(material, Material):
            raise InvalidArgumentError(
                f"material: got {type(material).__name__}, expected a Material or None"
            )
        self.objects.append((mesh, material or Material()))
        return self

    def build(self) -> RenderScene:
        """Build the BVH over all triangles (object index = position in :attr:`objects`)."""
        for name in ("objects", "lights"):
            if not isinstance(getattr(self, name), (list, tuple)):
                got = type(getattr(self, name)).__name__
                raise InvalidArgumentError(f"{name}: got {got}, expected a list")
        verts, tris, obj = [], [], []
        offset = 0
        for k, item in enumerate(self.objects):
            mesh, material = item if isinstance(item, tuple) and len(item) == 2 else (None, None)
            if not isinstance(mesh, Mesh) or not isinstance(material, Material):
                raise InvalidArgumentError(
                    f"objects[{k}]: got {item!r:.60}, expected a (Mesh, Material) pair"
                )
            verts.append(mesh.vertices)
            tris.append(mesh.triangles + np.uint32(offset))
            obj.append(np.full(len(mesh.triangles), k, np.uint32))
            offset += len(mesh.vertices)
        v = np.concatenate(verts) if verts else np.zeros((0, 3), np.float32)
        t = np.concatenate(tris) if tris else np.zeros((0, 3), np.uint32)
        o = np.concatenate(obj) if obj else np.zeros(0, np.uint32)
        amb = _grey_or_rgb("ambient", self.ambient)
        for k, light in enumerate(self.lights):
            if not isinstance(light, PointLight):
                raise InvalidArgumentError(
                    f"lights[{k}]: got {type(light).__name__}, expected a PointLight"
                )
        native = _rgbd_rs.NativeScene(
            np.ascontiguousarray(v, np.float32),
            np.ascontiguousarray(t, np.uint32),
            o,
            [m._native() for _, m in self.objects],
            [light._native() for light in self.lights],
            amb,
        )
        return RenderScene(native)


class RenderScene:
    """A built scene (BVH ready). Renders from any camera and pose; thread-safe."""

    def __init__(self, native: _rgbd_rs.NativeScene) -> None:
        self._native = native

    @property
    def triangle_count(self) -> int:
        """Number of triangles."""
        return self._native.triangle_count

    def depth(self, camera: Camera, pose: Pose | None = None) -> F32:
        """First-hit depth z (metres), NaN where nothing is hit."""
        return self._native.depth(_view(camera, pose))

    def gbuffer(self, camera: Camera, pose: Pose | None = None) -> GBuffer:
        """Depth, normals, triangle/object ids and barycentrics of the first hits."""
        return GBuffer(*self._native.gbuffer(_view(camera, pose)))

    def color(
        self,
        camera: Camera,
        pose: Pose | None = None,
        *,
        supersample: int = 2,
        shadows: bool = True,
    ) -> F32:
        """Linear RGB radiance (H x W x 3 float32) with ``supersample^2`` rays per pixel."""
        shadows = _validate.flag("shadows", shadows)
        ss = _validate.integer("supersample", supersample, minimum=1, maximum=8)
        return self._native.color(_view(camera, pose), ss, bool(shadows))

    def tof(
        self,
        camera: PinholeCamera,
        pose: Pose | None = None,
        model: ToFModel | None = None,
        *,
        seed: int = 0,
    ) -> ToFFrame:
        """Simulate a ToF frame (emitter at the camera centre) with ``model``'s error sources."""
        m = ToFModel() if model is None else model
        if not isinstance(m, ToFModel):
            raise InvalidArgumentError(f"model: got {type(m).__name__}, expected a ToFModel")
        if not isinstance(camera, PinholeCamera):
            raise InvalidArgumentError(
                f"camera: got {type(camera).__name__}, expected a PinholeCamera for ToF"
            )
        return ToFFrame(
            *self._native.tof(
                _view(camera, pose),
                float(m.frequency_hz),  # the fields were validated by ToFModel itself
                int(m.subsamples),
                int(m.multipath_rays),
                bool(m.noise),
                float(m.power),
                float(m.read_noise),
                float(m.shot_noise),
                float(m.ambient),
                float(m.amplitude_threshold),
                bool(m.wrap_phase),
                _validate.integer("seed", seed, maximum=2**63 - 1),
            )
        )


def render_points(
    points: npt.ArrayLike, camera: Camera, pose: Pose | None = None, *, radius: float
) -> tuple[F32, I32]:
    """Splat ``N x 3`` points as camera-facing disks of world ``radius``.

    Returns ``(depth, index)``: z of the nearest disk per pixel (NaN where empty) and the index
    of the point that drew it (-1 where empty).
    """
    pts = _validate.array("points", points, shape=(None, 3), finite=True, allow_empty=True)
    r = _validate.real("radius", radius, positive=True)
    return _rgbd_rs.render_points(pts, r, _view(camera, pose))
