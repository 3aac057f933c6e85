//! A renderable scene: one BVH over all triangles, the object (material) of each triangle,
//! point lights and ambient light.

use rgbd_geom::error::{check_len, invalid};
use rgbd_geom::Result;

use crate::bvh::{Bvh, Hit};
use crate::material::Material;
use crate::math::{add, cross, dot, normalize, scale, V3};
use crate::view::Ray;

/// An isotropic point light: RGB intensity (radiance scale at 1 m) at a world position.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct PointLight {
    pub position: V3,
    pub intensity: [f32; 3],
}

/// What a ray hit, resolved for shading.
#[derive(Debug, Clone, Copy)]
pub struct Surface {
    /// World position.
    pub p: V3,
    /// Unit geometric normal, flipped to face the incoming ray.
    pub n: V3,
    /// Object index (into the material list).
    pub object: u32,
}

/// Triangles + BVH + materials + lights.
#[derive(Debug, Clone)]
pub struct Scene {
    bvh: Bvh,
    normals: Vec<V3>,
    object: Vec<u32>,
    pub materials: Vec<Material>,
    pub lights: Vec<PointLight>,
    pub ambient: [f32; 3],
}

impl Scene {
    /// Builds a scene from flat buffers: `vertices` (n x 3, metres, world frame), `triangles`
    /// (m x 3 vertex indices), `object` (m, an index into `materials` per triangle).
    pub fn new(
        vertices: &[f32],
        triangles: &[u32],
        object: &[u32],
        materials: Vec<Material>,
        lights: Vec<PointLight>,
        ambient: [f32; 3],
    ) -> Result<Self> {
        if !vertices.len().is_multiple_of(3) {
            return Err(invalid(
                "vertices",
                vertices.len(),
                "a multiple of 3 values (n x 3)",
            ));
        }
        if !triangles.len().is_multiple_of(3) {
            return Err(invalid(
                "triangles",
                triangles.len(),
                "a multiple of 3 indices (m x 3)",
            ));
        }
        let (nv, nt) = (vertices.len() / 3, triangles.len() / 3);
        check_len("object", object, nt, "one object index per triangle")?;
        if let Some(bad) = vertices.iter().find(|v| !v.is_finite()) {
            return Err(invalid("vertices", bad, "finite coordinates"));
        }
        if let Some(&bad) = triangles.iter().find(|&&i| i as usize >= nv) {
            return Err(invalid("triangles", bad, format!("vertex indices < {nv}")));
        }
        if let Some(&bad) = object.iter().find(|&&o| o as usize >= materials.len()) {
            return Err(invalid(
                "object",
                bad,
                format!(
                    "material indices < {} (the number of materials)",
                    materials.len()
                ),
            ));
        }
        for m in &materials {
            m.validate()?;
        }
        for l in &lights {
            if !l.position.iter().chain(&l.intensity).all(|v| v.is_finite())
                || l.intensity.iter().any(|&i| i < 0.0)
            {
                return Err(invalid(
                    "light",
                    format!("{l:?}"),
                    "finite position, intensity >= 0",
                ));
            }
        }
        if !ambient.iter().all(|a| a.is_finite() && *a >= 0.0) {
            return Err(invalid(
                "ambient",
                format!("{ambient:?}"),
                "finite values >= 0",
            ));
        }
        let vtx = |i: u32| -> V3 {
            let k = 3 * i as usize;
            [vertices[k], vertices[k + 1], vertices[k + 2]]
        };
        let tris: Vec<[V3; 3]> = triangles
            .chunks_exact(3)
            .map(|t| [vtx(t[0]), vtx(t[1]), vtx(t[2])])
            .collect();
        let normals = tris
            .iter()
            .map(|t| {
                let e1 = [t[1][0] - t[0][0], t[1][1] - t[0][1], t[1][2] - t[0][2]];
                let e2 = [t[2][0] - t[0][0], t[2][1] - t[0][1], t[2][2] - t[0][2]];
                normalize(cross(e1, e2))
            })
            .collect();
        Ok(Self {
            bvh: Bvh::build(&tris),
            normals,
            object: object.to_vec(),
            materials,
            lights,
            ambient,
        })
    }

    /// The acceleration structure.
    pub fn bvh(&self) -> &Bvh {
        &self.bvh
    }

    /// Number of triangles.
    pub fn triangle_count(&self) -> usize {
        self.object.len()
    }

    /// Nearest hit of `ray` beyond `t_min`.
    #[inline]
    pub fn cast(&self, ray: &Ray, t_min: f32) -> Option<Hit> {
        self.bvh.closest(ray.o, ray.d, t_min, f32::INFINITY)
    }

    /// Nearest hits of eight rays beyond `t_min` (coherent rays: see [`Bvh::closest8`]).
    #[inline]
    pub fn cast8(&self, rays: &[Ray; 8], t_min: f32) -> [Option<Hit>; 8] {
        let o = rays.map(|r| r.o);
        let d = rays.map(|r| r.d);
        self.bvh.closest8(&o, &d, t_min, f32::INFINITY)
    }

    /// Resolves a hit of `ray` into position, facing normal and object.
    #[inline]
    pub fn surface(&self, ray: &Ray, hit: &Hit) -> Surface {
        let n = self.normals[hit.prim as usize];
        let n = if dot(n, ray.d) > 0.0 {
            scale(n, -1.0)
        } else {
            n
        };
        Surface {
            p: add(ray.o, scale(ray.d, hit.t)),
            n,
            object: self.object[hit.prim as usize],
        }
    }

    /// The material of a surface.
    #[inline]
    pub fn material(&self, s: &Surface) -> &Material {
        &self.materials[s.object as usize]
    }
}
