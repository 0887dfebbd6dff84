//! Textures: values that vary over a surface, looked up at its uv.
pub mod bitmap;
