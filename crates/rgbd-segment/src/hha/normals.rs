//! Normals by least-squares planes in square windows: per-column sums sliding down a band,
//! window moments along the row, one 3x3 solve per pixel (see the module docs of `hha`).

use super::*;

simd_dispatch! {
    pub(super) fn slide_columns(
        cols: &mut [Vec<f64>; 5],
        r: usize,
        enter: (&[f64], f64),
        leave: (&[f64], f64),
    ) {
        let [cw, cwy, cwyy, cq, cqy] = cols;
        let n = enter.0.len();
        let (cw, cwy, cwyy) = (&mut cw[r..r + n], &mut cwy[r..r + n], &mut cwyy[r..r + n]);
        let (cq, cqy) = (&mut cq[r..r + n], &mut cqy[r..r + n]);
        let ((q_in, y_in), (q_out, y_out)) = (enter, leave);
        let (q_out, yy_in, yy_out) = (&q_out[..n], y_in * y_in, y_out * y_out);
        for i in 0..n {
            let (qi, qo) = (q_in[i], q_out[i]);
            // Branch-free: a pixel that does not take part has q = 0 and adds nothing.
            let wi = if qi > 0.0 { 1.0 } else { 0.0 };
            let wo = if qo > 0.0 { 1.0 } else { 0.0 };
            cw[i] += wi - wo;
            cwy[i] += wi * y_in - wo * y_out;
            cwyy[i] += wi * yy_in - wo * yy_out;
            cq[i] += qi - qo;
            cqy[i] += qi * y_in - qo * y_out;
        }
    }
}

/// The nine window sums of a row, from absolute pixel coordinates `(x, y)` of the points:
/// `Σw, Σwx, Σwx², Σwy, Σwxy, Σwy², Σq, Σqx, Σqy` (`w` = 1 where the pixel takes part, `q` =
/// `1/z` or 0). The `w` sums are integers, exact in f64.
pub(super) const SUMS: usize = 9;

/// The window sums of the `q` moments (`Σq, Σqx, Σqy`, sums 6 to 8) of a row from the column
/// sums `cq, cqy`: prefix sums along the row, two columns per step (the dependency chain is half
/// as long), then differences `n` apart.
#[inline(always)]
pub(super) fn q_window_sums(
    cq: &[f64],
    cqy: &[f64],
    xs_pad: &[f64],
    n: usize,
    prefix: &mut [Vec<f64>; SUMS],
    sums: &mut [Vec<f64>; SUMS],
) {
    let len = cq.len();
    let (cqy, xs_pad) = (&cqy[..len], &xs_pad[..len]);
    let [.., p6, p7, p8] = prefix.each_mut().map(|p| {
        p.resize(len + 1, 0.0);
        &mut p[..len + 1]
    });
    let value = |j: usize| [cq[j], cq[j] * xs_pad[j], cqy[j]];
    let mut acc = [0.0f64; 3];
    let mut j = 0;
    while j + 2 <= len {
        let (v0, v1) = (value(j), value(j + 1));
        p6[j + 1] = acc[0] + v0[0];
        p7[j + 1] = acc[1] + v0[1];
        p8[j + 1] = acc[2] + v0[2];
        for k in 0..3 {
            acc[k] += v0[k] + v1[k];
        }
        p6[j + 2] = acc[0];
        p7[j + 2] = acc[1];
        p8[j + 2] = acc[2];
        j += 2;
    }
    if j < len {
        let v0 = value(j);
        p6[j + 1] = acc[0] + v0[0];
        p7[j + 1] = acc[1] + v0[1];
        p8[j + 1] = acc[2] + v0[2];
    }
    let w = len + 1 - n;
    for (p, out) in prefix[6..].iter().zip(sums[6..].iter_mut()) {
        let (lo, hi, out) = (&p[..w], &p[n..n + w], &mut out[..w]);
        for i in 0..w {
            out[i] = hi[i] - lo[i];
        }
    }
}

simd_dispatch! {
    /// The nine window sums ([`SUMS`]) of a row of windows `n` wide from the column sums
    /// `cols`: prefix sums along the row, then differences `n` apart (the `w` sums are
    /// integers, exact in any order).
    pub(super) fn window_row(
        cols: &[Vec<f64>; 5],
        xs_pad: &[f64],
        n: usize,
        prefix: &mut [Vec<f64>; SUMS],
        sums: &mut [Vec<f64>; SUMS],
    ) {
        let [cw, cwy, cwyy, cq, cqy] = cols.each_ref().map(|c| c.as_slice());
        let len = cw.len();
        let (cwy, cwyy, xs_pad) = (&cwy[..len], &cwyy[..len], &xs_pad[..len]);
        {
            let [p0, p1, p2, p3, p4, p5, ..] = prefix.each_mut().map(|p| {
                p.resize(len + 1, 0.0);
                &mut p[..len + 1]
            });
            let mut acc = [0.0f64; 6];
            for j in 0..len {
                let x = xs_pad[j];
                let v = [cw[j], cw[j] * x, cw[j] * x * x, cwy[j], cwy[j] * x, cwyy[j]];
                for k in 0..6 {
                    acc[k] += v[k];
                }
                p0[j + 1] = acc[0];
                p1[j + 1] = acc[1];
                p2[j + 1] = acc[2];
                p3[j + 1] = acc[3];
                p4[j + 1] = acc[4];
                p5[j + 1] = acc[5];
            }
        }
        let w = len + 1 - n;
        for (p, out) in prefix[..6].iter().zip(sums[..6].iter_mut()) {
            let (lo, hi, out) = (&p[..w], &p[n..n + w], &mut out[..w]);
            for i in 0..w {
                out[i] = hi[i] - lo[i];
            }
        }
        q_window_sums(cq, cqy, xs_pad, n, prefix, sums);
    }
}

/// `(count, Σ i, Σ i²)` over the integers `lo..=hi` (as f64: exact for the image sizes here).
pub(super) fn run_moments(lo: usize, hi: usize) -> [f64; 3] {
    // Σ_{i <= m} i² = m (m + 1) (2m + 1) / 6.
    let squares = |m: u128| m * (m + 1) * (2 * m + 1) / 6;
    let (l, h) = (lo as u128, hi as u128);
    let below = if lo == 0 { 0 } else { squares(l - 1) };
    [
        (h + 1 - l) as f64,
        ((l + h) * (h + 1 - l) / 2) as f64,
        (squares(h) - below) as f64,
    ]
}

simd_dispatch! {
    /// [`window_row`] for a row whose window rows are all taking part: the point counts and
    /// coordinate moments are products of the row moments `rows` (of the window's rows, see
    /// [`run_moments`]) and the column moments `columns` (per pixel, of its clipped columns),
    /// the same integers as [`window_row`] sums; only the `q` sums are summed along the row.
    pub(super) fn window_row_full(
        cols: &[Vec<f64>; 5],
        xs_pad: &[f64],
        n: usize,
        rows: [f64; 3],
        columns: &[Vec<f64>; 3],
        prefix: &mut [Vec<f64>; SUMS],
        sums: &mut [Vec<f64>; SUMS],
    ) {
        q_window_sums(&cols[3], &cols[4], xs_pad, n, prefix, sums);
        let w = cols[3].len() + 1 - n;
        let [nc, sx1, sx2] = columns.each_ref().map(|c| &c[..w]);
        let [nr, sy1, sy2] = rows;
        let [s0, s1, s2, s3, s4, s5, ..] = sums.each_mut().map(|s| &mut s[..w]);
        for i in 0..w {
            s0[i] = nr * nc[i];
            s1[i] = nr * sx1[i];
            s2[i] = nr * sx2[i];
            s3[i] = nc[i] * sy1;
            s4[i] = sx1[i] * sy1;
            s5[i] = nc[i] * sy2;
        }
    }
}

simd_dispatch! {
    pub(super) fn solve_row(
        sums: &[Vec<f64>; SUMS],
        xs: &[f64],
        y: f64,
        depth: &[f32],
        cam: &Pinhole,
        normals: &mut [Vec<f64>; 3],
    ) {
        let n = xs.len();
        let [b0, b1, b2, b3, b4, b5, b6, b7, b8] = sums;
        let (b0, b1, b2, b3, b4) = (&b0[..n], &b1[..n], &b2[..n], &b3[..n], &b4[..n]);
        let (b5, b6, b7, b8, depth) = (&b5[..n], &b6[..n], &b7[..n], &b8[..n], &depth[..n]);
        let [nx, ny, nz] = normals;
        let (nx, ny, nz) = (&mut nx[..n], &mut ny[..n], &mut nz[..n]);
        let (fx, fy, dy) = (cam.fx, cam.fy, cam.cy - y);
        for i in 0..n {
            let x = xs[i];
            // Moments about the window's own pixel (u = x' - x, v = y' - y): exact integers.
            let s1 = b0[i];
            let su = b1[i] - x * s1;
            let sv = b3[i] - y * s1;
            let suu = b2[i] - 2.0 * x * b1[i] + x * x * s1;
            let suv = b4[i] - x * b3[i] - y * b1[i] + x * y * s1;
            let svv = b5[i] - 2.0 * y * b3[i] + y * y * s1;
            let t1 = b6[i];
            let tu = b7[i] - x * t1;
            let tv = b8[i] - y * t1;
            // Adjugate of the normal matrix of q = α u + β v + γ (as the reference's
            // `invertIt`/`mutiplyIt`, in pixel units about the pixel).
            let c0 = svv * s1 - sv * sv;
            let c1 = -suv * s1 + su * sv;
            let c2 = suv * sv - su * svv;
            let c3 = suu * s1 - su * su;
            let c4 = -suu * sv + suv * su;
            let c5 = suu * svv - suv * suv;
            // det = s1³ x det(covariance of (u, v)): the spread of the points in the image.
            let det = suu * c0 + suv * c1 + su * c2;
            let alpha = c0 * tu + c1 * tv + c2 * t1;
            let beta = c1 * tu + c3 * tv + c4 * t1;
            let gamma = c2 * tu + c4 * tv + c5 * t1;
            // With a = (x - cx) / fx: q = n . (a, b, 1), n = (α fx, β fy, γ + α (cx - x) +
            // β (cy - y)), and n . (a, b, 1) at the pixel itself is γ.
            let (n0, n1) = (alpha * fx, beta * fy);
            let n2 = gamma + alpha * (cam.cx - x) + beta * dy;
            let norm2 = n0 * n0 + n1 * n1 + n2 * n2;
            let defined = s1 >= 2.5
                && det >= MIN_SPREAD_PX4 * s1 * s1 * s1
                && norm2 > 0.0
                && norm2 < f64::INFINITY;
            // Oriented as the reference: n_z >= 0, then n . p >= 0 where the depth is valid.
            let up = if n2 < 0.0 { -1.0 } else { 1.0 };
            let z = depth[i];
            let flip = z > 0.0 && z < f32::INFINITY && up * gamma < 0.0;
            let s = if flip { -up } else { up } / norm2.sqrt();
            let nan = f64::NAN;
            nx[i] = if defined { s * n0 } else { nan };
            ny[i] = if defined { s * n1 } else { nan };
            nz[i] = if defined { s * n2 } else { nan };
        }
    }
}

/// Rows per block of the sliding-window sums (fixed, so results do not depend on threads).
pub(super) const BAND: usize = 48;

/// The window sums of one band for half-size `r`, and the normals of its current row.
pub(super) struct Window {
    /// Per column, sums over the rows of the window, padded with `r` zeros on both sides:
    /// `Σw, Σwy, Σwy², Σq, Σqy`.
    pub(super) cols: [Vec<f64>; 5],
    /// `x` of every padded column (`-r` first).
    pub(super) xs_pad: Vec<f64>,
    pub(super) sums: [Vec<f64>; SUMS],
    pub(super) prefix: [Vec<f64>; SUMS],
    /// [`run_moments`] of every pixel's clipped window columns (count, Σx, Σx²).
    pub(super) columns: [Vec<f64>; 3],
    /// The current row's unit normals (x, y, z components), NaN where undefined, oriented as
    /// the reference (`n . p >= 0`).
    pub(super) n: [Vec<f64>; 3],
}

impl Window {
    pub(super) fn new(r: usize, width: usize) -> Self {
        let padded = width + 2 * r;
        Self {
            cols: std::array::from_fn(|_| vec![0.0; padded]),
            xs_pad: (0..padded).map(|j| j as f64 - r as f64).collect(),
            sums: std::array::from_fn(|_| vec![0.0; width]),
            prefix: std::array::from_fn(|_| vec![0.0; padded + 1]),
            columns: {
                let m: Vec<[f64; 3]> = (0..width)
                    .map(|x| run_moments(x.saturating_sub(r), (x + r).min(width - 1)))
                    .collect();
                std::array::from_fn(|k| m.iter().map(|v| v[k]).collect())
            },
            n: std::array::from_fn(|_| vec![0.0; width]),
        }
    }
}

/// What the normals are computed from.
pub(super) struct Support<'a> {
    pub(super) depth: &'a [f32],
    pub(super) iz: Vec<f64>,
    /// `partial_rows[y]`: how many of the rows above `y` have a pixel that takes no part.
    pub(super) partial_rows: Vec<usize>,
    pub(super) zeros: Vec<f64>,
    pub(super) width: usize,
    pub(super) height: usize,
    pub(super) cam: Pinhole,
}

impl<'a> Support<'a> {
    pub(super) fn new(
        depth: &'a [f32],
        raw: Option<&[f32]>,
        width: usize,
        height: usize,
        cam: &Pinhole,
    ) -> Self {
        let iz = inverse_depth(depth, raw);
        let partial: Vec<bool> = iz
            .par_chunks(width.max(1))
            .map(|row| row.iter().any(|&q| q <= 0.0))
            .collect();
        let mut partial_rows = vec![0; height + 1];
        for (y, &p) in partial.iter().enumerate() {
            partial_rows[y + 1] = partial_rows[y] + usize::from(p);
        }
        Self {
            depth,
            iz,
            partial_rows,
            zeros: vec![0.0; width],
            width,
            height,
            cam: *cam,
        }
    }

    pub(super) fn bands(&self) -> usize {
        self.height.div_ceil(BAND)
    }

    /// The `1/z` row `y` with its `y`, or zeros when there is no such row.
    pub(super) fn row(&self, y: Option<usize>) -> (&[f64], f64) {
        match y {
            Some(y) => (&self.iz[y * self.width..][..self.width], y as f64),
            None => (&self.zeros, 0.0),
        }
    }

    /// Normals of the rows of band `band` for windows of half-size `r`: `emit(row in band,
    /// window)` with the row's normals in `window.n`. Per column, `cols` slides down the
    /// rows; along the row, window sums come from runs of power-of-two length. Each normal is
    /// solved from the moments about its own pixel, oriented as the reference: first
    /// `n_z >= 0`, then `n . p >= 0` where the pixel's depth is valid.
    pub(super) fn band(
        &self,
        band: usize,
        r: usize,
        mut emit: impl FnMut(usize, &Window) -> Result<()>,
    ) -> Result<()> {
        let (width, height) = (self.width, self.height);
        let mut win = Window::new(r, width);
        let y_start = band * BAND;
        let xs = &win.xs_pad[r..r + width].to_vec();
        for yy in y_start.saturating_sub(r)..(y_start + r).min(height) {
            slide_columns(&mut win.cols, r, self.row(Some(yy)), self.row(None));
        }
        for y in y_start..(y_start + BAND).min(height) {
            check_interrupt()?;
            // Enter row y + r, leave row y - r - 1.
            let enter = (y + r < height).then_some(y + r);
            let leave = (y > y_start && y > r).then(|| y - r - 1);
            slide_columns(&mut win.cols, r, self.row(enter), self.row(leave));
            let Window {
                cols,
                xs_pad,
                sums,
                n,
                prefix,
                columns,
            } = &mut win;
            let (lo, hi) = (y.saturating_sub(r), (y + r).min(height - 1));
            if self.partial_rows[hi + 1] == self.partial_rows[lo] {
                let rows = run_moments(lo, hi);
                window_row_full(cols, xs_pad, 2 * r + 1, rows, columns, prefix, sums);
            } else {
                window_row(cols, xs_pad, 2 * r + 1, prefix, sums);
            }
            let depth = &self.depth[y * width..][..width];
            solve_row(sums, xs, y as f64, depth, &self.cam, n);
            emit(y - y_start, &win)?;
        }
        Ok(())
    }
}

/// Unit surface normals (`H x W x 3` f32, NaN where undefined) from least-squares planes in
/// `(2 radius + 1)^2` windows of the back-projected `depth` (metres), as the reference's
/// `computeNormalsSquareSupport`. Pixels missing in `depth`, or in `raw` when given, do not take
/// part. Oriented toward the camera (`n . p <= 0`) if `toward_camera`, else as the reference
/// (`n . p >= 0`).
pub fn normals(
    depth: &[f32],
    raw: Option<&[f32]>,
    width: usize,
    height: usize,
    cam: &Pinhole,
    radius: usize,
    toward_camera: bool,
) -> Result<Vec<f32>> {
    check_inputs(depth, raw, width, height, cam)?;
    if radius == 0 || radius > width.max(height) {
        return Err(invalid(
            "radius",
            radius,
            format!("1..={} (the image's larger side)", width.max(height)),
        ));
    }
    let flip = if toward_camera { -1.0 } else { 1.0 };
    let support = Support::new(depth, raw, width, height, cam);
    let mut out = vec![0.0f32; 3 * width * height];
    out.par_chunks_mut(3 * BAND * width)
        .enumerate()
        .try_for_each(|(band, out)| {
            support.band(band, radius, |dy, win| {
                let row = &mut out[3 * dy * width..][..3 * width];
                let [nx, ny, nz] = &win.n;
                for (((o, &x), &y), &z) in row.chunks_exact_mut(3).zip(nx).zip(ny).zip(nz) {
                    o.copy_from_slice(&[(flip * x) as f32, (flip * y) as f32, (flip * z) as f32]);
                }
                Ok(())
            })
        })?;
    Ok(out)
}
