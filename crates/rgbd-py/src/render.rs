//! Thin adapters for `rgbd-render`: a built scene is a Python object (BVH built once), views and
//! materials arrive as plain tuples assembled by `python/rgbd_rs/render.py`.

use std::sync::Arc;

use numpy::prelude::*;
use numpy::{PyArray2, PyArray3, PyReadonlyArray1, PyReadonlyArray2, PyReadonlyArray3};
use pyo3::prelude::*;
use rgbd_render::{Material, Pattern, PointLight, Projection, Scene, TofOptions, View};

use crate::errors::{borrow, run, run_interruptible, InvalidArgumentError};
use crate::geom::{pose, to_numpy, PoseArgs};

/// `(kind, a, b, cx, cy, width, height, world_to_camera)`: kind "perspective" (a, b = fx, fy)
/// or "orthographic" (a, b = pixels per metre).
type ViewArgs = (String, f64, f64, f64, f64, usize, usize, PoseArgs);
/// `(albedo, albedo_ir, contrast, kind, params, seed, image)`, see `Material._native()`.
type MaterialArgs<'py> = (
    [f32; 3],
    f32,
    f32,
    String,
    Vec<f32>,
    u64,
    Option<PyReadonlyArray3<'py, f32>>,
);
/// `(position, rgb intensity)`.
type LightArgs = ([f32; 3], [f32; 3]);

fn view(v: ViewArgs) -> PyResult<View> {
    let (kind, a, b, cx, cy, w, h, p) = v;
    let projection = match kind.as_str() {
        "perspective" => Projection::Perspective {
            fx: a,
            fy: b,
            cx,
            cy,
        },
        "orthographic" => Projection::Orthographic {
            sx: a,
            sy: b,
            cx,
            cy,
        },
        other => {
            return Err(InvalidArgumentError::new_err(format!(
                "view: got projection {other:?}, expected 'perspective' or 'orthographic'"
            )))
        }
    };
    View::new(projection, w, h, &pose(p)?).map_err(crate::errors::to_py)
}

fn param(kind: &str, params: &[f32], n: usize) -> PyResult<()> {
    if params.len() == n {
        Ok(())
    } else {
        Err(InvalidArgumentError::new_err(format!(
            "texture {kind}: got {} parameters, expected {n}",
            params.len()
        )))
    }
}

fn material(m: MaterialArgs<'_>) -> PyResult<Material> {
    let (albedo, albedo_ir, contrast, kind, p, seed, image) = m;
    let pattern = match kind.as_str() {
        "uniform" => Pattern::Uniform,
        "checker" => {
            param(&kind, &p, 1)?;
            Pattern::Checker { period: p[0] }
        }
        "stripes" => {
            param(&kind, &p, 2)?;
            Pattern::Stripes {
                period: p[0],
                angle: p[1],
            }
        }
        "noise" => {
            param(&kind, &p, 1)?;
            Pattern::Noise { scale: p[0], seed }
        }
        "image" => {
            param(&kind, &p, 1)?;
            let img = image.ok_or_else(|| {
                InvalidArgumentError::new_err("texture image: got no image, expected H x W x 3")
            })?;
            let s = img.shape();
            Pattern::Image {
                width: s[1],
                height: s[0],
                rgb: borrow("texture image", &img)?.to_vec(),
                period: p[0],
            }
        }
        other => {
            return Err(InvalidArgumentError::new_err(format!(
                "texture: got kind {other:?}, expected uniform/checker/stripes/noise/image"
            )))
        }
    };
    Ok(Material {
        albedo,
        albedo_ir,
        pattern,
        contrast,
    })
}

/// A scene with its BVH built, ready to render from any number of views.
#[pyclass(module = "rgbd_rs._rgbd_rs", name = "NativeScene", frozen)]
pub struct PyScene {
    inner: Arc<Scene>,
}

#[pymethods]
impl PyScene {
    #[new]
    fn new(
        py: Python<'_>,
        vertices: PyReadonlyArray2<'_, f32>,
        triangles: PyReadonlyArray2<'_, u32>,
        object: PyReadonlyArray1<'_, u32>,
        materials: Vec<MaterialArgs<'_>>,
        lights: Vec<LightArgs>,
        ambient: [f32; 3],
    ) -> PyResult<Self> {
        let mats = materials
            .into_iter()
            .map(material)
            .collect::<PyResult<Vec<_>>>()?;
        let lights = lights
            .into_iter()
            .map(|(position, intensity)| PointLight {
                position,
                intensity,
            })
            .collect();
        let v = borrow("vertices", &vertices)?;
        let t = borrow("triangles", &triangles)?;
        let o = borrow("object", &object)?;
        let scene = run(py, || Scene::new(v, t, o, mats, lights, ambient))?;
        Ok(Self {
            inner: Arc::new(scene),
        })
    }

    /// Number of triangles.
    #[getter]
    fn triangle_count(&self) -> usize {
        self.inner.triangle_count()
    }

    /// First-hit depth (z, metres; NaN on misses), `H x W`.
    fn depth<'py>(&self, py: Python<'py>, v: ViewArgs) -> PyResult<Bound<'py, PyArray2<f32>>> {
        let view = view(v)?;
        let s = &self.inner;
        let out = run_interruptible(py, || rgbd_render::render_depth(s, &view))?;
        to_numpy(py, (view.height, view.width), out)
    }

    /// `(depth, normal, prim, object, bary)` of the first hits.
    #[allow(clippy::type_complexity)]
    fn gbuffer<'py>(
        &self,
        py: Python<'py>,
        v: ViewArgs,
    ) -> PyResult<(
        Bound<'py, PyArray2<f32>>,
        Bound<'py, PyArray3<f32>>,
        Bound<'py, PyArray2<i32>>,
        Bound<'py, PyArray2<i32>>,
        Bound<'py, PyArray3<f32>>,
    )> {
        let view = view(v)?;
        let s = &self.inner;
        let g = run_interruptible(py, || rgbd_render::render_gbuffer(s, &view))?;
        let (h, w) = (view.height, view.width);
        Ok((
            to_numpy(py, (h, w), g.depth)?,
            to_numpy(py, (h, w, 3), g.normal)?,
            to_numpy(py, (h, w), g.prim)?,
            to_numpy(py, (h, w), g.object)?,
            to_numpy(py, (h, w, 2), g.bary)?,
        ))
    }

    /// Linear RGB radiance, `H x W x 3`.
    fn color<'py>(
        &self,
        py: Python<'py>,
        v: ViewArgs,
        supersample: usize,
        shadows: bool,
    ) -> PyResult<Bound<'py, PyArray3<f32>>> {
        let view = view(v)?;
        let s = &self.inner;
        let out = run_interruptible(py, || {
            rgbd_render::render_color(s, &view, supersample, shadows)
        })?;
        to_numpy(py, (view.height, view.width, 3), out)
    }

    /// `(depth, amplitude, true depth)` of a simulated ToF frame.
    #[allow(clippy::too_many_arguments, clippy::type_complexity)]
    fn tof<'py>(
        &self,
        py: Python<'py>,
        v: ViewArgs,
        frequency_hz: f64,
        subsamples: usize,
        multipath_rays: usize,
        noise: bool,
        power: f32,
        read_noise: f32,
        shot_noise: f32,
        ambient: f32,
        amplitude_threshold: f32,
        wrap_phase: bool,
        seed: u64,
    ) -> PyResult<(
        Bound<'py, PyArray2<f32>>,
        Bound<'py, PyArray2<f32>>,
        Bound<'py, PyArray2<f32>>,
    )> {
        let view = view(v)?;
        let opts = TofOptions {
            frequency_hz,
            subsamples,
            multipath_rays,
            noise,
            power,
            read_noise,
            shot_noise,
            ambient,
            amplitude_threshold,
            wrap_phase,
            seed,
        };
        let s = &self.inner;
        let f = run_interruptible(py, || rgbd_render::simulate_tof(s, &view, &opts))?;
        let (h, w) = (view.height, view.width);
        Ok((
            to_numpy(py, (h, w), f.depth)?,
            to_numpy(py, (h, w), f.amplitude)?,
            to_numpy(py, (h, w), f.truth)?,
        ))
    }
}

type Splats<'py> = (Bound<'py, PyArray2<f32>>, Bound<'py, PyArray2<i32>>);

/// Point cloud (`N x 3`) splatted as disks of world `radius`: `(depth, point index)`.
#[pyfunction]
pub fn render_points<'py>(
    py: Python<'py>,
    points: PyReadonlyArray2<'py, f32>,
    radius: f32,
    v: ViewArgs,
) -> PyResult<Splats<'py>> {
    let view = view(v)?;
    let pts = borrow("points", &points)?;
    let (d, i) = run_interruptible(py, || rgbd_render::render_points(pts, radius, &view))?;
    Ok((
        to_numpy(py, (view.height, view.width), d)?,
        to_numpy(py, (view.height, view.width), i)?,
    ))
}
