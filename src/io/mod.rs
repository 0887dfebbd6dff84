//! Image input and output.
pub mod exr;
pub mod png;
