//! Line charts written as SVG, for the figures the README links to: the host tool's
//! implementation (`inertia::close_loop::plot`), shared so the two cannot drift apart.

pub use inertia::close_loop::plot::{write_svg, Chart, Series};
