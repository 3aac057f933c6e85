//! `rgbd_rs._rgbd_rs`: the private native module. Public Python modules wrap these functions;
//! this crate only adapts numpy buffers to the core crates and maps their errors.

use pyo3::prelude::*;

mod clues;
mod errors;
mod fusion;
mod geom;
mod hha;
mod oversegment;
mod render;
mod segment;
mod sources;
mod spline;
mod stereo;
mod views;
mod voxel;

/// Number of threads rayon uses in this process (set `RAYON_NUM_THREADS` before import; in a
/// forked child, 1 unless `RAYON_NUM_THREADS` says otherwise).
#[pyfunction]
#[pyo3(name = "num_threads")]
fn py_num_threads() -> usize {
    num_threads()
}

/// See [`py_num_threads`].
pub(crate) fn num_threads() -> usize {
    if errors::is_fork_child() {
        fork_child_threads()
    } else {
        rayon_threads()
    }
}

/// Asks the native kernels running now (on any thread) to stop at their next check, as Ctrl-C
/// does on the thread that called them; nothing when none runs. For a caller whose kernel runs on
/// a worker thread and that itself caught `KeyboardInterrupt`.
#[pyfunction]
fn interrupt_running() {
    rgbd_error::interrupt_running();
}

/// Forgets, in a forked child, the native calls the parent was running at the fork (called by
/// `rgbd_rs._fork` through `os.register_at_fork`; see `rgbd_error::reset_after_fork`).
#[pyfunction]
fn after_fork_in_child() {
    rgbd_error::reset_after_fork();
}

/// `RAYON_NUM_THREADS` when set to a positive count.
fn requested_threads() -> Option<usize> {
    std::env::var("RAYON_NUM_THREADS")
        .ok()
        .and_then(|v| v.parse().ok())
        .filter(|&n: &usize| n > 0)
}

/// The global pool's threads: `RAYON_NUM_THREADS`, else the cores (rayon's own rule; a count
/// above the cores was reported as the cores while the pool ran that many).
pub(crate) fn rayon_threads() -> usize {
    rayon::current_num_threads()
}

/// Threads of a forked child's pool: one, as torch gives its DataLoader workers, since a fork is
/// usually one of several workers sharing the cores (N workers of a full-size pool each would
/// run N x cores threads); `RAYON_NUM_THREADS` overrides it.
pub(crate) fn fork_child_threads() -> usize {
    let cores = std::thread::available_parallelism().map_or(1, |n| n.get());
    requested_threads().map_or(1, |n| n.min(cores))
}

#[pymodule]
fn _rgbd_rs(m: &Bound<'_, PyModule>) -> PyResult<()> {
    errors::record_parent();
    let py = m.py();
    m.add("RgbdError", py.get_type::<errors::RgbdError>())?;
    m.add(
        "InvalidArgumentError",
        py.get_type::<errors::InvalidArgumentError>(),
    )?;
    m.add(
        "ShapeMismatchError",
        py.get_type::<errors::ShapeMismatchError>(),
    )?;
    m.add_function(wrap_pyfunction!(py_num_threads, m)?)?;
    m.add_function(wrap_pyfunction!(interrupt_running, m)?)?;
    m.add_function(wrap_pyfunction!(after_fork_in_child, m)?)?;
    m.add_function(wrap_pyfunction!(errors::use_side_pool, m)?)?;
    m.add_function(wrap_pyfunction!(geom::project_points, m)?)?;
    m.add_function(wrap_pyfunction!(geom::land_points, m)?)?;
    m.add_function(wrap_pyfunction!(geom::undistort_pixels, m)?)?;
    m.add_function(wrap_pyfunction!(geom::distort_pixels, m)?)?;
    m.add_function(wrap_pyfunction!(geom::depth_to_points, m)?)?;
    m.add_function(wrap_pyfunction!(geom::undistort_map, m)?)?;
    m.add_function(wrap_pyfunction!(geom::remap, m)?)?;
    m.add_function(wrap_pyfunction!(geom::undistort_image, m)?)?;
    m.add_function(wrap_pyfunction!(geom::depth_disparity, m)?)?;
    m.add_function(wrap_pyfunction!(geom::reproject_depth, m)?)?;
    m.add_function(wrap_pyfunction!(geom::normals_from_points, m)?)?;
    m.add_function(wrap_pyfunction!(spline::fit_surface, m)?)?;
    m.add_function(wrap_pyfunction!(spline::view_curvatures, m)?)?;
    m.add_function(wrap_pyfunction!(spline::depth_view_curvatures, m)?)?;
    m.add_class::<spline::PySegmentFits>()?;
    m.add_class::<render::PyScene>()?;
    m.add_function(wrap_pyfunction!(render::render_points, m)?)?;
    m.add_function(wrap_pyfunction!(fusion::label_regions, m)?)?;
    m.add_function(wrap_pyfunction!(fusion::mean_shift_filter, m)?)?;
    m.add_function(wrap_pyfunction!(fusion::cost_curve_stats, m)?)?;
    m.add_function(wrap_pyfunction!(clues::clue_warp_maps, m)?)?;
    m.add_function(wrap_pyfunction!(clues::agreement, m)?)?;
    m.add_function(wrap_pyfunction!(sources::fill_single_source, m)?)?;
    m.add_function(wrap_pyfunction!(sources::unseen_from_tof, m)?)?;
    m.add_function(wrap_pyfunction!(sources::extend_tof_into_band, m)?)?;
    m.add_function(wrap_pyfunction!(sources::carry_tof_to_border, m)?)?;
    m.add_function(wrap_pyfunction!(sources::bridge_band_across_dropouts, m)?)?;
    m.add_function(wrap_pyfunction!(clues::clue_maps, m)?)?;
    m.add_function(wrap_pyfunction!(clues::normalise_clues, m)?)?;
    m.add_function(wrap_pyfunction!(fusion::upsample_depth, m)?)?;
    m.add_function(wrap_pyfunction!(fusion::lc_fuse, m)?)?;
    m.add_class::<fusion::PyLcConfig>()?;
    m.add_class::<fusion::PyUpsampleConfig>()?;
    // Each segmentation module registers its own functions (one owner per file).
    hha::register(m)?;
    oversegment::register(m)?;
    segment::register(m)?;
    voxel::register(m)?;
    stereo::register(m)?;
    views::register(m)?;
    // Limits defined once in the core crates, read by the Python layer.
    m.add("MAX_RADIUS", rgbd_fusion::MAX_RADIUS)?;
    m.add("MAX_SIDE", rgbd_error::MAX_SIDE)?;
    m.add("MAX_PIXELS", rgbd_error::MAX_PIXELS)?;
    m.add("MAX_ELEMENTS", rgbd_error::MAX_ELEMENTS)?;
    m.add("SPLINE_MAX_DEGREE", rgbd_spline::MAX_DEGREE)?;
    m.add("SPLINE_DEFAULT_LAMBDA", rgbd_spline::DEFAULT_LAMBDA)?;
    // The fused map's source codes, defined where the steps after LC write them.
    {
        use rgbd_fusion::sources::*;
        m.add("SOURCE_NONE", SOURCE_NONE)?;
        m.add("SOURCE_LC", SOURCE_LC)?;
        m.add("SOURCE_TOF", SOURCE_TOF)?;
        m.add("SOURCE_STEREO", SOURCE_STEREO)?;
        m.add("SOURCE_TOF_CARRIED", SOURCE_TOF_CARRIED)?;
        m.add("SOURCE_LC_UNMEASURED", SOURCE_LC_UNMEASURED)?;
    }
    Ok(())
}
