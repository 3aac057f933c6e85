//! Triangle / axis-aligned box overlap by the separating axis theorem (Akenine-Möller 2001):
//! the box's 3 face normals, the triangle's normal and the 9 edge cross products.

type V = [f64; 3];

fn sub(a: V, b: V) -> V {
    [a[0] - b[0], a[1] - b[1], a[2] - b[2]]
}

fn cross(a: V, b: V) -> V {
    [
        a[1] * b[2] - a[2] * b[1],
        a[2] * b[0] - a[0] * b[2],
        a[0] * b[1] - a[1] * b[0],
    ]
}

fn dot(a: V, b: V) -> f64 {
    a[0] * b[0] + a[1] * b[1] + a[2] * b[2]
}

/// Whether triangle `t` (three corners) overlaps the box of centre `c` and half-size `h`
/// (touching counts as overlapping, so a triangle on a voxel face marks both voxels).
#[allow(clippy::needless_range_loop)] // indexes the three corners per axis
pub fn overlaps(t: [V; 3], c: V, h: f64) -> bool {
    let v = [sub(t[0], c), sub(t[1], c), sub(t[2], c)];
    // Box face normals: the triangle's extent along x, y, z.
    for a in 0..3 {
        let lo = v[0][a].min(v[1][a]).min(v[2][a]);
        let hi = v[0][a].max(v[1][a]).max(v[2][a]);
        if lo > h || hi < -h {
            return false;
        }
    }
    let e = [sub(v[1], v[0]), sub(v[2], v[1]), sub(v[0], v[2])];
    let separated = |axis: V| {
        let r = h * (axis[0].abs() + axis[1].abs() + axis[2].abs());
        let p = [dot(v[0], axis), dot(v[1], axis), dot(v[2], axis)];
        let (lo, hi) = (p[0].min(p[1]).min(p[2]), p[0].max(p[1]).max(p[2]));
        lo > r || hi < -r
    };
    for edge in e {
        for unit in [[1.0, 0.0, 0.0], [0.0, 1.0, 0.0], [0.0, 0.0, 1.0]] {
            if separated(cross(unit, edge)) {
                return false;
            }
        }
    }
    !separated(cross(e[0], e[1]))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn plane_through_the_box_and_beside_it() {
        let t = [[-5.0, -5.0, 0.2], [5.0, -5.0, 0.2], [0.0, 5.0, 0.2]];
        assert!(overlaps(t, [0.0; 3], 0.5));
        assert!(!overlaps(t, [0.0, 0.0, 1.0], 0.5));
        // Touching a face counts.
        assert!(overlaps(t, [0.0, 0.0, 0.7], 0.5));
    }

    #[test]
    fn diagonal_miss_needs_an_edge_axis() {
        // A sliver beside the box corner: every face-normal interval overlaps the box, only
        // the triangle normal or an edge cross product separates it.
        let t = [[1.2, 0.0, -1.0], [0.0, 1.2, -1.0], [0.0, 1.2, 1.0]];
        assert!(!overlaps(t, [0.0; 3], 0.5));
        assert!(overlaps(t, [0.0; 3], 0.7));
    }
}
