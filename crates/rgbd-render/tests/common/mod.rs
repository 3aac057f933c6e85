//! Small analytic scenes shared by the integration tests.
#![allow(dead_code)]

use rgbd_geom::Pose;
use rgbd_render::{Material, Pattern, Projection, Scene, TofOptions, View};

pub struct Builder {
    pub v: Vec<f32>,
    pub t: Vec<u32>,
    pub obj: Vec<u32>,
}

impl Builder {
    pub fn new() -> Self {
        Self {
            v: vec![],
            t: vec![],
            obj: vec![],
        }
    }

    /// An axis-aligned quad given by its four corners (counter-clockwise).
    pub fn quad(&mut self, c: [[f32; 3]; 4], object: u32) -> &mut Self {
        let b = (self.v.len() / 3) as u32;
        c.iter().for_each(|p| self.v.extend(p));
        self.t.extend([b, b + 1, b + 2, b, b + 2, b + 3]);
        self.obj.extend([object, object]);
        self
    }

    /// The plane z = `z` spanning +-`half` in x and y.
    pub fn wall(&mut self, z: f32, half: f32, object: u32) -> &mut Self {
        self.quad(
            [
                [-half, -half, z],
                [half, -half, z],
                [half, half, z],
                [-half, half, z],
            ],
            object,
        )
    }

    /// The scene with every triangle from the `first_quad`-th quad on using object 1.
    pub fn scene_with(&self, materials: Vec<Material>, first_quad: usize) -> Scene {
        let obj: Vec<u32> = (0..self.obj.len())
            .map(|i| u32::from(i >= 2 * first_quad))
            .collect();
        Scene::new(&self.v, &self.t, &obj, materials, vec![], [1.0; 3]).unwrap()
    }

    pub fn scene(&self, materials: Vec<Material>) -> Scene {
        Scene::new(&self.v, &self.t, &self.obj, materials, vec![], [1.0; 3]).unwrap()
    }
}

pub fn grey(ir: f32) -> Material {
    Material {
        albedo: [0.5; 3],
        albedo_ir: ir,
        pattern: Pattern::Uniform,
        contrast: 0.0,
    }
}

pub fn pinhole(w: usize, h: usize, f: f64) -> View {
    let p = Projection::Perspective {
        fx: f,
        fy: f,
        cx: (w as f64 - 1.0) / 2.0,
        cy: (h as f64 - 1.0) / 2.0,
    };
    View::new(p, w, h, &Pose::identity()).unwrap()
}

/// Every effect off: the ToF measures the true depth exactly.
pub fn ideal() -> TofOptions {
    TofOptions {
        frequency_hz: 120e6,
        subsamples: 1,
        multipath_rays: 0,
        noise: false,
        power: 4000.0,
        read_noise: 2.0,
        shot_noise: 0.4,
        ambient: 10.0,
        amplitude_threshold: 0.0,
        wrap_phase: false,
        seed: 0,
    }
}

pub fn finite_mean(v: impl Iterator<Item = f32>) -> f64 {
    let (s, n) = v
        .filter(|x| x.is_finite())
        .fold((0.0, 0usize), |(s, n), x| (s + x as f64, n + 1));
    s / n as f64
}
