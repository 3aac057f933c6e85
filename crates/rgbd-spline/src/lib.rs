//! B-spline (NURBS with unit weights) surfaces on a knot grid anchored to the image lattice
//! (thesis §4.5, §5.3.3). Work in progress (issue 5): so far the uniform basis with derivatives.

pub mod basis;

pub use basis::{uniform_basis, Basis, BasisError, MAX_DEGREE};
