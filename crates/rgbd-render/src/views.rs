//! The six orthographic depth views of a shape (thesis §5.3.1): depth maps seen from the six
//! faces of its bounding cube, for triangle meshes (first hit of one ray per pixel through the
//! [`Bvh`]) and for point clouds (z-buffered camera-facing disks, "splats").
//!
//! **Frame.** The shape is placed in the cube of [`Cube::fit`] (the convention of rgbd-voxel's
//! grid): the largest bounding-box extent spans the cube and the shape is centred along the
//! other axes; a zero-extent box (a single point) gets a cube of side 1. z is up (ModelNet).
//!
//! **Views**, in this order, each `res x res`, row 0 at the top, column 0 on the left, pixel
//! centres at `(j + 0.5) / res` of the cube side ([`VIEW_AXES`] gives right, up, forward):
//!
//! | k | seen from | right | up  | looks along |
//! |---|-----------|-------|-----|-------------|
//! | 0 | +x side   | +y    | +z  | -x          |
//! | 1 | +y side   | -x    | +z  | -y          |
//! | 2 | -x side   | -y    | +z  | +x          |
//! | 3 | -y side   | +x    | +z  | +y          |
//! | 4 | top (+z)  | +x    | +y  | -z          |
//! | 5 | bottom (-z) | -x  | +y  | +z          |
//!
//! The side views go round the vertical axis counter-clockwise (seen from above): rotating the
//! shape by +90° about z moves side view k's image unchanged to view k+1 (mod 4) and turns the
//! top and bottom images by 90°. Every view is a proper rotation (no mirrored image).
//!
//! **Depth** is the distance from the cube face into the shape in units of the cube side (0 on
//! the face, 1 on the opposite face); pixels that see nothing are NaN.

use rayon::prelude::*;
use rgbd_error::{check_interrupt, invalid, Result};

use rgbd_geom::shape::used_vertices;
pub use rgbd_geom::shape::{Cube, MAX_EXTENT};

use crate::bvh::Bvh;
use crate::math::V3;

/// Number of views: four sides, top, bottom.
pub const VIEWS: usize = 6;
/// Largest view side in pixels.
pub const MAX_RESOLUTION: usize = 2048;
/// Automatic splat radii (see [`auto_splat_radii`]): each point's disk is this many times the
/// distance to its [`SPLAT_NEIGHBOURS`]-th nearest neighbour, so the disks follow the local
/// density (dense parts stay sharp, sparse faces close). For points scattered uniformly at
/// random over a surface with density `l`, that distance is about `sqrt(8 / (pi l))`, and disks
/// of `0.8` of it (`~1.28 / sqrt(l)`) leave about `exp(-pi 1.28^2) = 0.6 %` of the surface
/// uncovered.
pub const SPLAT_KNN_FACTOR: f64 = 0.8;
/// The neighbour whose distance sets a point's splat radius.
pub const SPLAT_NEIGHBOURS: usize = 8;
/// Largest `k` of [`knn_distances`].
pub const MAX_NEIGHBOURS: usize = 32;
/// Automatic radii are capped at this many times their median (an isolated outlier point stays a
/// small blob).
pub const SPLAT_MEDIAN_CAP: f64 = 3.0;
/// Smallest automatic splat radius in pixels: `sqrt(2) / 2`, so a disk always covers the pixel
/// its point falls in, whatever the position (a dense cloud then renders like one point per
/// pixel, a z-buffered point projection).
pub const MIN_SPLAT_PX: f64 = std::f64::consts::FRAC_1_SQRT_2;
/// Largest splat radius accepted, in pixels.
pub const MAX_SPLAT_PX: f64 = 64.0;
/// Rays start this far (cube sides) outside the near face, so surfaces lying on the face (a
/// box's own faces) are hit.
const RAY_MARGIN: f32 = 1e-3;

/// `(right, up, forward)` of each view as `(axis, sign)`; see the module table.
pub const VIEW_AXES: [[(usize, f32); 3]; VIEWS] = [
    [(1, 1.0), (2, 1.0), (0, -1.0)],
    [(0, -1.0), (2, 1.0), (1, -1.0)],
    [(1, -1.0), (2, 1.0), (0, 1.0)],
    [(0, 1.0), (2, 1.0), (1, 1.0)],
    [(0, 1.0), (1, 1.0), (2, -1.0)],
    [(0, -1.0), (1, 1.0), (2, 1.0)],
];

fn check_resolution(res: usize) -> Result<()> {
    if (1..=MAX_RESOLUTION).contains(&res) {
        Ok(())
    } else {
        Err(invalid(
            "resolution",
            res,
            format!("1..={MAX_RESOLUTION} pixels per side"),
        ))
    }
}

/// The unit vector of `(axis, sign)`.
#[inline]
fn unit((a, s): (usize, f32)) -> V3 {
    let mut v = [0.0; 3];
    v[a] = s;
    v
}

/// `(column, row, depth)` of a cube-frame point in view `k` at resolution `res` (continuous
/// pixel coordinates, pixel centres at integers; depth in cube sides from the near face).
#[inline]
fn project(p: V3, k: usize, res: usize) -> (f32, f32, f32) {
    let [(ra, rs), (ua, us), (fa, fs)] = VIEW_AXES[k];
    let r = res as f32;
    (
        (rs * p[ra] + 0.5) * r - 0.5,
        (0.5 - us * p[ua]) * r - 0.5,
        fs * p[fa] + 0.5,
    )
}

/// Checks a mesh and returns the cube of the vertices its faces use (stray vertices would
/// shrink the shape) with the triangles in cube coordinates.
fn mesh_in_cube(vertices: &[f32], faces: &[u32]) -> Result<(Cube, Vec<[V3; 3]>)> {
    let pts = used_vertices(vertices, faces)?;
    let cube = Cube::fit(&pts)?;
    let v = |i: u32| cube.normalize(&vertices[3 * i as usize..3 * i as usize + 3]);
    let tris = faces
        .chunks_exact(3)
        .map(|f| [v(f[0]), v(f[1]), v(f[2])])
        .collect();
    Ok((cube, tris))
}

/// The six views of the mesh `vertices` (`n x 3`) / `faces` (`m x 3`): `6 * res * res` depths
/// (view, row, column), NaN where nothing is seen. Each view is z-buffer rasterized, sampling
/// every triangle at the pixel centres it covers (edges inclusive, so shared edges leave no
/// crack), views in parallel: the same first-surface depth as [`mesh_views_raycast`] (one ray
/// per pixel centre) at a fraction of the cost, since all rays of a view are parallel to an
/// axis. Triangles seen exactly edge-on are invisible (a flat mesh has empty side views).
pub fn mesh_views(vertices: &[f32], faces: &[u32], res: usize) -> Result<Vec<f32>> {
    check_resolution(res)?;
    let (_, tris) = mesh_in_cube(vertices, faces)?;
    let mut out = vec![f32::INFINITY; VIEWS * res * res];
    out.par_chunks_mut(res * res)
        .enumerate()
        .try_for_each(|(k, view)| -> Result<()> {
            for (n, t) in tris.iter().enumerate() {
                if n % 65536 == 0 {
                    check_interrupt()?;
                }
                raster(t.map(|p| project(p, k, res)), res, view);
            }
            Ok(())
        })?;
    out.iter_mut()
        .filter(|d| d.is_infinite())
        .for_each(|d| *d = f32::NAN);
    Ok(out)
}

/// Z-buffers one projected triangle (`(column, row, depth)` corners) into `view`.
#[inline]
fn raster(t: [(f32, f32, f32); 3], res: usize, view: &mut [f32]) {
    let [a, b, c] = t.map(|(u, v, z)| (f64::from(u), f64::from(v), f64::from(z)));
    let last = res as f64 - 1.0;
    let c0 = a.0.min(b.0).min(c.0).ceil().max(0.0);
    let c1 = a.0.max(b.0).max(c.0).floor().min(last);
    let r0 = a.1.min(b.1).min(c.1).ceil().max(0.0);
    let r1 = a.1.max(b.1).max(c.1).floor().min(last);
    if !(c0 <= c1 && r0 <= r1) {
        return;
    }
    // Twice the signed area; edge-on triangles (zero area) cover nothing.
    let area = (b.0 - a.0) * (c.1 - a.1) - (b.1 - a.1) * (c.0 - a.0);
    if area == 0.0 || !area.is_finite() {
        return;
    }
    let s = area.signum();
    let inv = 1.0 / area.abs();
    // Edge function of the edge p -> q at (x, y), positive inside for either winding.
    let edge = |p: (f64, f64, f64), q: (f64, f64, f64)| {
        let (ea, eb) = (s * (p.1 - q.1), s * (q.0 - p.0));
        (ea, eb, -(ea * p.0 + eb * p.1))
    };
    let (e0, e1, e2) = (edge(b, c), edge(c, a), edge(a, b));
    for row in r0 as usize..=r1 as usize {
        let y = row as f64;
        let line = &mut view[row * res..(row + 1) * res];
        for (col, d) in line
            .iter_mut()
            .enumerate()
            .take(c1 as usize + 1)
            .skip(c0 as usize)
        {
            let x = col as f64;
            let w0 = e0.0 * x + e0.1 * y + e0.2;
            let w1 = e1.0 * x + e1.1 * y + e1.2;
            let w2 = e2.0 * x + e2.1 * y + e2.2;
            if w0 >= 0.0 && w1 >= 0.0 && w2 >= 0.0 {
                let z = ((w0 * a.2 + w1 * b.2 + w2 * c.2) * inv).clamp(0.0, 1.0) as f32;
                if z < *d {
                    *d = z;
                }
            }
        }
    }
}

/// [`mesh_views`] by ray casting: one BVH, one ray per pixel centre starting just outside the
/// near face, rows of all views in parallel. The reference the rasterizer is tested against.
pub fn mesh_views_raycast(vertices: &[f32], faces: &[u32], res: usize) -> Result<Vec<f32>> {
    check_resolution(res)?;
    let (_, tris) = mesh_in_cube(vertices, faces)?;
    let bvh = Bvh::build(&tris);
    let mut out = vec![f32::NAN; VIEWS * res * res];
    let r = res as f32;
    out.par_chunks_mut(res)
        .enumerate()
        .try_for_each(|(row_id, row)| -> Result<()> {
            check_interrupt()?;
            let (k, i) = (row_id / res, row_id % res);
            let [right, up, fwd] = VIEW_AXES[k].map(unit);
            let y = 0.5 - (i as f32 + 0.5) / r;
            for (j, d) in row.iter_mut().enumerate() {
                let x = (j as f32 + 0.5) / r - 0.5;
                let o = [0, 1, 2].map(|a| right[a] * x + up[a] * y - fwd[a] * (0.5 + RAY_MARGIN));
                if let Some(h) = bvh.closest(o, fwd, 0.0, 1.0 + 2.0 * RAY_MARGIN) {
                    *d = (h.t - RAY_MARGIN).clamp(0.0, 1.0);
                }
            }
            Ok(())
        })?;
    Ok(out)
}

/// Checks a point cloud and returns it in cube coordinates.
fn points_in_cube(points: &[f32]) -> Result<Vec<V3>> {
    let cube = Cube::fit(points)?;
    Ok(points.chunks_exact(3).map(|p| cube.normalize(p)).collect())
}

/// Distance from each point to its `k`-th nearest other point (cube units, `k <= 32`), via a uniform grid
/// of about `sqrt(n) / 2.5` cells per side; fewer than `k` other points: the farthest one (0 for a
/// single point).
pub fn knn_distances(pts: &[V3], k: usize) -> Vec<f32> {
    let n = pts.len();
    let k = k.clamp(1, n.saturating_sub(1).clamp(1, MAX_NEIGHBOURS));
    if n < 2 {
        return vec![0.0; n];
    }
    // Surface samples in a unit cube: spacing ~ 1/sqrt(n) and the 8th neighbour ~2.5 spacings
    // away, so cells of ~2.5 / sqrt(n) usually find it within the 27 cells around a point;
    // capped so the cell table stays small (128^3 u32 = 8 MB).
    let g = (((n as f64).sqrt() / 2.5).round() as usize).clamp(1, 128);
    let gi = g as isize;
    let cell = 1.0 / g as f32;
    let idx = |v: f32| (((v + 0.5) * g as f32) as isize).clamp(0, gi - 1);
    let key = |c: [isize; 3]| (c[0] + gi * (c[1] + gi * c[2])) as usize;
    let cells: Vec<[isize; 3]> = pts.iter().map(|p| p.map(idx)).collect();
    // Counting sort of the points by cell.
    let mut start = vec![0u32; g * g * g + 1];
    for c in &cells {
        start[key(*c) + 1] += 1;
    }
    for i in 0..g * g * g {
        start[i + 1] += start[i];
    }
    let mut fill = start.clone();
    let mut sorted = vec![0u32; n];
    for (i, c) in cells.iter().enumerate() {
        let s = &mut fill[key(*c)];
        sorted[*s as usize] = i as u32;
        *s += 1;
    }
    (0..n)
        .into_par_iter()
        .with_min_len(256)
        .map(|i| {
            let (p, c) = (pts[i], cells[i]);
            // The k smallest squared distances so far, ascending.
            let mut buf = [f32::INFINITY; MAX_NEIGHBOURS];
            let best = &mut buf[..k];
            for shell in 0..=gi {
                // Cells at Chebyshev distance exactly `shell` from c.
                for dz in -shell..=shell {
                    for dy in -shell..=shell {
                        for dx in -shell..=shell {
                            if dx.abs().max(dy.abs()).max(dz.abs()) != shell {
                                continue;
                            }
                            let q = [c[0] + dx, c[1] + dy, c[2] + dz];
                            if q.iter().any(|&v| v < 0 || v >= gi) {
                                continue;
                            }
                            let kk = key(q);
                            for &o in &sorted[start[kk] as usize..start[kk + 1] as usize] {
                                if o as usize == i {
                                    continue;
                                }
                                let d = pts[o as usize];
                                let e = (p[0] - d[0]).powi(2)
                                    + (p[1] - d[1]).powi(2)
                                    + (p[2] - d[2]).powi(2);
                                if e < best[k - 1] {
                                    let at = best.partition_point(|&b| b <= e);
                                    best.copy_within(at..k - 1, at + 1);
                                    best[at] = e;
                                }
                            }
                        }
                    }
                }
                // Anything in the next shell or beyond is at least `shell` cells away.
                if best[k - 1].sqrt() <= shell as f32 * cell {
                    break;
                }
            }
            let found = best
                .iter()
                .rposition(|b| b.is_finite())
                .map_or(0.0, |j| best[j]);
            found.sqrt()
        })
        .collect()
}

fn median(v: &[f32]) -> f32 {
    let mut v = v.to_vec();
    let mid = v.len() / 2;
    *v.select_nth_unstable_by(mid, f32::total_cmp).1
}

/// The automatic per-point splat radii in pixels of a cloud (cube units) viewed at `res`:
/// `SPLAT_KNN_FACTOR` times each point's distance to its `SPLAT_NEIGHBOURS`-th nearest
/// neighbour, clamped to `[MIN_SPLAT_PX, min(MAX_SPLAT_PX, SPLAT_MEDIAN_CAP * median)]`.
pub fn auto_splat_radii(pts: &[V3], res: usize) -> Vec<f32> {
    let scale = SPLAT_KNN_FACTOR * res as f64;
    let mut r: Vec<f32> = knn_distances(pts, SPLAT_NEIGHBOURS)
        .iter()
        .map(|&d| (f64::from(d) * scale) as f32)
        .collect();
    let cap = (SPLAT_MEDIAN_CAP * f64::from(median(&r))).clamp(MIN_SPLAT_PX, MAX_SPLAT_PX);
    r.iter_mut()
        .for_each(|x| *x = f64::from(*x).clamp(MIN_SPLAT_PX, cap) as f32);
    r
}

/// [`auto_splat_radii`] of the cloud `points` (`n x 3`, input units) at `res`.
pub fn splat_radii(points: &[f32], res: usize) -> Result<Vec<f32>> {
    check_resolution(res)?;
    Ok(auto_splat_radii(&points_in_cube(points)?, res))
}

fn check_radius(radius: f32) -> Result<()> {
    if radius.is_finite() && f64::from(radius) > 0.0 && f64::from(radius) <= MAX_SPLAT_PX {
        Ok(())
    } else {
        Err(invalid(
            "splat_radius",
            radius,
            format!("a radius in (0, {MAX_SPLAT_PX}] pixels"),
        ))
    }
}

/// View `k` of cube-frame points drawn as disks of `radii[i]` pixels, z-buffered (nearest
/// wins).
fn splat_view(pts: &[V3], k: usize, res: usize, radii: &[f32], out: &mut [f32]) {
    out.fill(f32::INFINITY);
    let last = res as f32 - 1.0;
    for (&p, &radius) in pts.iter().zip(radii) {
        let r2 = radius * radius;
        let (u, v, z) = project(p, k, res);
        let (r0, r1) = ((v - radius).ceil().max(0.0), (v + radius).floor().min(last));
        if !(r0 <= r1) {
            continue;
        }
        for row in r0 as usize..=r1 as usize {
            // The disk's span on this row.
            let dv = row as f32 - v;
            let half = (r2 - dv * dv).max(0.0).sqrt();
            let (c0, c1) = ((u - half).ceil().max(0.0), (u + half).floor().min(last));
            if !(c0 <= c1) {
                continue;
            }
            for d in &mut out[row * res + c0 as usize..=row * res + c1 as usize] {
                if z < *d {
                    *d = z;
                }
            }
        }
    }
    out.iter_mut()
        .filter(|d| d.is_infinite())
        .for_each(|d| *d = f32::NAN);
}

/// The cloud in cube coordinates and its splat radii (`radius` for all, or automatic).
fn cloud(points: &[f32], res: usize, radius: Option<f32>) -> Result<(Vec<V3>, Vec<f32>)> {
    let pts = points_in_cube(points)?;
    let radii = match radius {
        Some(r) => vec![r; pts.len()],
        None => auto_splat_radii(&pts, res),
    };
    Ok((pts, radii))
}

/// The six views of the point cloud `points` (`n x 3`): `6 * res * res` depths, NaN where no
/// disk covers the pixel. `radius` is one disk radius in pixels for every point, or `None` for
/// [`auto_splat_radii`]. Returns the views and the median radius used.
pub fn point_views(points: &[f32], res: usize, radius: Option<f32>) -> Result<(Vec<f32>, f32)> {
    check_resolution(res)?;
    if let Some(r) = radius {
        check_radius(r)?;
    }
    let (pts, radii) = cloud(points, res, radius)?;
    check_interrupt()?;
    let mut out = vec![0.0f32; VIEWS * res * res];
    out.par_chunks_mut(res * res)
        .enumerate()
        .for_each(|(k, view)| splat_view(&pts, k, res, &radii, view));
    Ok((out, median(&radii)))
}

/// [`point_views`] of many clouds, in parallel over the clouds: `clouds.len() * 6 * res * res`
/// depths and the median radius used for each.
pub fn point_views_batch(
    clouds: &[&[f32]],
    res: usize,
    radius: Option<f32>,
) -> Result<(Vec<f32>, Vec<f32>)> {
    check_resolution(res)?;
    if let Some(r) = radius {
        check_radius(r)?;
    }
    let per = VIEWS * res * res;
    rgbd_error::checked_len("views", &[clouds.len(), per])?;
    let mut out = vec![0.0f32; clouds.len() * per];
    let radii = out
        .par_chunks_mut(per)
        .zip(clouds.par_iter())
        .map(|(views, points)| -> Result<f32> {
            check_interrupt()?;
            let (pts, radii) = cloud(points, res, radius)?;
            for (k, view) in views.chunks_mut(res * res).enumerate() {
                splat_view(&pts, k, res, &radii, view);
            }
            Ok(median(&radii))
        })
        .collect::<Result<Vec<f32>>>()?;
    Ok((out, radii))
}

/// Local contrast normalisation of each `height x width` map of `maps` (row-major, one map after
/// the other), in place, maps in parallel: with `B` the sum over the `window x window` box
/// centred on a pixel (zeros outside the map) and `N = B(1)` the pixels it holds,
/// `v = x - B(x) / N`, `sigma = sqrt(B(v^2) / N)`, `y = v / max(sigma, mean(sigma), eps)`
/// (Jarrett et al. 2009 with Torch's border correction). Integral images make the cost
/// independent of the window.
pub fn local_contrast_normalize(
    maps: &mut [f32],
    height: usize,
    width: usize,
    window: usize,
    eps: f64,
) -> Result<()> {
    rgbd_error::image_len("maps", width, height)?;
    let per = height * width;
    if maps.is_empty() || !maps.len().is_multiple_of(per) {
        return Err(invalid(
            "maps",
            format!("{} values", maps.len()),
            format!("a non-empty multiple of {height} x {width}"),
        ));
    }
    if window.is_multiple_of(2) {
        return Err(invalid("window", window, "an odd number of pixels"));
    }
    if !(eps > 0.0 && eps.is_finite()) {
        return Err(invalid("eps", eps, "a finite number > 0"));
    }
    if maps.iter().any(|v| !v.is_finite()) {
        return Err(invalid("maps", "non-finite values", "finite values"));
    }
    let h = window / 2;
    maps.par_chunks_mut(per).try_for_each(|m| -> Result<()> {
        check_interrupt()?;
        let (w1, mut integral) = (width + 1, vec![0.0f64; (height + 1) * (width + 1)]);
        let fill = |m: &[f64], s: &mut [f64]| {
            for i in 0..height {
                let mut row = 0.0;
                for j in 0..width {
                    row += m[i * width + j];
                    s[(i + 1) * w1 + j + 1] = s[i * w1 + j + 1] + row;
                }
            }
        };
        // Box sum and pixel count around (i, j).
        let boxed = |s: &[f64], i: usize, j: usize| {
            let (r0, r1) = (i.saturating_sub(h), (i + h + 1).min(height));
            let (c0, c1) = (j.saturating_sub(h), (j + h + 1).min(width));
            let sum = s[r1 * w1 + c1] - s[r0 * w1 + c1] - s[r1 * w1 + c0] + s[r0 * w1 + c0];
            (sum, ((r1 - r0) * (c1 - c0)) as f64)
        };
        let x: Vec<f64> = m.iter().map(|&v| f64::from(v)).collect();
        fill(&x, &mut integral);
        let v: Vec<f64> = (0..per)
            .map(|k| {
                let (sum, n) = boxed(&integral, k / width, k % width);
                x[k] - sum / n
            })
            .collect();
        let v2: Vec<f64> = v.iter().map(|a| a * a).collect();
        fill(&v2, &mut integral);
        let sigma: Vec<f64> = (0..per)
            .map(|k| {
                let (sum, n) = boxed(&integral, k / width, k % width);
                (sum / n).max(0.0).sqrt()
            })
            .collect();
        let floor = (sigma.iter().sum::<f64>() / per as f64).max(eps);
        for (o, (a, s)) in m.iter_mut().zip(v.iter().zip(&sigma)) {
            *o = (a / s.max(floor)) as f32;
        }
        Ok(())
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    /// An axis-aligned box `[lo, hi]` as 12 triangles.
    fn cuboid(lo: V3, hi: V3) -> (Vec<f32>, Vec<u32>) {
        let mut v = vec![];
        for i in 0..8 {
            v.extend([0, 1, 2].map(|a| if i >> a & 1 == 1 { hi[a] } else { lo[a] }));
        }
        let quads = [
            [0, 2, 3, 1],
            [4, 5, 7, 6],
            [0, 1, 5, 4],
            [2, 6, 7, 3],
            [0, 4, 6, 2],
            [1, 3, 7, 5],
        ];
        let f = quads
            .iter()
            .flat_map(|q| [q[0], q[1], q[2], q[0], q[2], q[3]])
            .collect();
        (v, f)
    }

    #[test]
    fn view_axes_are_proper_rotations() {
        for axes in VIEW_AXES {
            let [r, u, f] = axes.map(unit);
            let c = crate::math::cross(r, u);
            assert_eq!(c, f.map(|x| -x), "right x up = -forward (camera y down)");
        }
    }

    #[test]
    fn a_cube_is_flat_in_every_view() {
        let (v, f) = cuboid([-1.0, -1.0, -1.0], [1.0, 1.0, 1.0]);
        for d in [mesh_views(&v, &f, 16), mesh_views_raycast(&v, &f, 16)] {
            let d = d.unwrap();
            assert!(d.iter().all(|&x| x.abs() < 1e-4), "{d:?}");
        }
    }

    #[test]
    fn a_slab_is_centred_and_seen_at_its_depth() {
        // 2 x 1 x 0.5: the cube side is 2, so from +x the slab is 1 deep face-to-face and the
        // side views show it in the middle half (y) and middle quarter (z).
        let (v, f) = cuboid([0.0, 0.0, 0.0], [2.0, 1.0, 0.5]);
        let res = 8;
        let d = mesh_views(&v, &f, res).unwrap();
        let dr = mesh_views_raycast(&v, &f, res).unwrap();
        for (x, y) in d.iter().zip(&dr) {
            assert!(
                x == y || (x - y).abs() < 1e-5 || (x.is_nan() && y.is_nan()),
                "{x} {y}"
            );
        }
        let at = |k: usize, i: usize, j: usize| d[(k * res + i) * res + j];
        // View 1 (from +y): depth = (1 - 0.5) / 2 = 0.25 from the face; x spans everything.
        assert!((at(1, 4, 0) - 0.25).abs() < 1e-4);
        assert!(at(1, 0, 4).is_nan() && at(1, 2, 4).is_nan() && at(1, 3, 4) < 1.0);
        // Top view: z extent 0.5 centred in the 2-cube: depth 0.75 / 2 = 0.375.
        assert!((at(4, 4, 4) - 0.375).abs() < 1e-4);
        // From +x the slab spans half the columns (y) only.
        assert!(at(0, 4, 1).is_nan() && (at(0, 4, 3) - 0.0).abs() < 1e-4);
    }

    /// A UV sphere of radius `r` at `c` (`rings x segs x 2` triangles).
    fn uv_sphere(c: V3, r: f32, rings: usize, segs: usize) -> (Vec<f32>, Vec<u32>) {
        let (mut v, mut f) = (vec![], vec![]);
        for i in 0..=rings {
            let th = std::f32::consts::PI * i as f32 / rings as f32;
            for j in 0..segs {
                let ph = std::f32::consts::TAU * j as f32 / segs as f32;
                v.extend([
                    c[0] + r * th.sin() * ph.cos(),
                    c[1] + r * th.sin() * ph.sin(),
                    c[2] + r * th.cos(),
                ]);
            }
        }
        for i in 0..rings as u32 {
            for j in 0..segs as u32 {
                let s = segs as u32;
                let (a, b) = (i * s + j, i * s + (j + 1) % s);
                f.extend([a, b, a + s, b, b + s, a + s]);
            }
        }
        (v, f)
    }

    #[test]
    fn rasterizer_matches_the_ray_caster() {
        // Two overlapping spheres: occlusion, silhouettes, every view.
        let (mut v, mut f) = uv_sphere([0.0, 0.0, 0.0], 1.0, 24, 48);
        let (v2, f2) = uv_sphere([0.7, 0.3, 0.5], 0.6, 16, 32);
        let base = (v.len() / 3) as u32;
        v.extend(v2);
        f.extend(f2.iter().map(|i| i + base));
        let res = 48;
        let a = mesh_views(&v, &f, res).unwrap();
        let b = mesh_views_raycast(&v, &f, res).unwrap();
        let differ = a
            .iter()
            .zip(&b)
            .filter(|(x, y)| !((x.is_nan() && y.is_nan()) || (*x - *y).abs() < 1e-4))
            .count();
        // Only pixel centres within rounding of a silhouette edge may differ.
        assert!(differ * 1000 < a.len(), "{differ} of {}", a.len());
        assert!(a.iter().filter(|x| !x.is_nan()).count() * 3 > a.len());
    }

    #[test]
    fn lcn_of_a_constant_is_zero_and_of_a_step_is_signed() {
        let mut m = vec![2.0f32; 2 * 20];
        local_contrast_normalize(&mut m, 4, 10, 3, 1e-4).unwrap();
        assert!(m.iter().all(|v| v.abs() < 1e-6));
        let mut step: Vec<f32> = (0..100)
            .map(|k| if k % 10 < 5 { 0.0 } else { 1.0 })
            .collect();
        local_contrast_normalize(&mut step, 10, 10, 3, 1e-4).unwrap();
        assert!(step[4] < -0.5 && step[5] > 0.5 && step[0].abs() < 1e-6);
        assert!(local_contrast_normalize(&mut step, 10, 10, 4, 1e-4).is_err());
        assert!(local_contrast_normalize(&mut step, 10, 9, 3, 1e-4).is_err());
    }

    #[test]
    fn points_and_errors() {
        let pts = [0.0f32, 0.0, 0.0];
        let (d, r) = point_views(&pts, 5, None).unwrap();
        assert_eq!(splat_radii(&pts, 5).unwrap().len(), 1);
        assert!((f64::from(r) - MIN_SPLAT_PX).abs() < 1e-6);
        // One point at the centre of a unit cube: the centre pixel at depth 0.5 in every view.
        for k in 0..VIEWS {
            assert!((d[k * 25 + 12] - 0.5).abs() < 1e-6);
            assert_eq!(
                d[k * 25..(k + 1) * 25]
                    .iter()
                    .filter(|x| x.is_nan())
                    .count(),
                24
            );
        }
        assert!(point_views(&pts, 0, None).is_err());
        assert!(point_views(&pts, 5, Some(0.0)).is_err());
        assert!(point_views(&[], 5, None).is_err());
        assert!(point_views(&[f32::NAN, 0.0, 0.0], 5, None).is_err());
        assert!(mesh_views(&pts, &[0, 0, 1], 5).is_err());
    }

    #[test]
    fn spacing_of_a_grid_is_its_step() {
        let mut pts = vec![];
        for i in 0..20 {
            for j in 0..20 {
                pts.push([i as f32 * 0.05 - 0.5, j as f32 * 0.05 - 0.5, 0.0]);
            }
        }
        // Interior points of a grid: 4 neighbours at one step, 4 at sqrt(2) steps.
        let d = knn_distances(&pts, 8);
        assert!((d[10 * 20 + 10] - 0.05 * 2f32.sqrt()).abs() < 1e-5);
        assert!((knn_distances(&pts, 1)[0] - 0.05).abs() < 1e-5);
        let batch = [
            [0.0f32, 0.0, 0.0, 1.0, 0.0, 0.0].as_slice(),
            [0.0f32; 3].as_slice(),
        ];
        let (d, radii) = point_views_batch(&batch, 4, None).unwrap();
        assert_eq!((d.len(), radii.len()), (2 * 6 * 16, 2));
    }
}
