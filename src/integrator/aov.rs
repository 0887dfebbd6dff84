//! Mitsuba's `aov` integrator (arbitrary output variables): what the camera ray sees first,
//! per pixel, for inspection and as denoiser input — `depth` (distance along the camera
//! ray from its origin: the camera's position, or the near plane of an orthographic camera,
//! as in Mitsuba), `position` (world space), `geo_normal`, `sh_normal`, `uv` and `albedo` (the diffuse
//! reflectance, Mitsuba's `eval_diffuse_reflectance`: π · f(wi, n) cos θ, which is the
//! reflectance of a diffuse surface) — and the images of nested integrators, written as
//! named channels of one OpenEXR file with Mitsuba's names (`dd.T` for `dd:depth`, `nn.X`,
//! `nn.Y`, `nn.Z` for `nn:sh_normal`, `my_image.R/G/B` for a nested `<integrator
//! name="my_image">`). A ray that hits nothing gives 0, as in Mitsuba. Values are averaged
//! over each pixel's samples through the reconstruction filter like colours.
//!
//! Differences from Mitsuba 3.9.1, both documented choices: `sh_normal` is the shading
//! normal before normal and bump maps (Mitsuba's comes from the BSDF's frame, with them), and
//! nested integrators give R, G, B without an alpha channel.
//!
//! Each channel group (a nested integrator's RGB, or one AOV) is rendered as a pass of its
//! own with the same seed, so all groups see the same pixel samples
//! ([`crate::render::render_channels`]).

use crate::geometry::Ray;
use crate::integrator::{Integrator, PathStats};
use crate::sampler::SampleStream;
pub use crate::scene::description::AovKind;
use crate::scene::Scene;
use crate::spectrum::{from_rgb, rgb, Spectrum};
use glam::{Vec3, Vec4};

#[derive(Clone, Debug)]
pub struct AovIntegrator {
    /// `(name, type)` in the order of the `aovs` string.
    pub aovs: Vec<(String, AovKind)>,
    /// Nested integrators by name, rendered into `name.R/G/B`.
    pub nested: Vec<(String, Integrator)>,
    /// The camera's world position: the scene is built around the camera, `position` is
    /// reported in world space.
    pub world_origin: Vec3,
    /// The channel group the integrator currently renders: nested integrators first, then
    /// the AOVs ([`render_channels`] steps through them).
    pub group: usize,
}

impl AovIntegrator {
    /// Channel names and widths of every group, in order.
    pub fn groups(&self) -> Vec<(String, &'static [&'static str])> {
        const RGB: &[&str] = &["R", "G", "B"];
        self.nested
            .iter()
            .map(|(name, _)| (name.clone(), RGB))
            .chain(
                self.aovs
                    .iter()
                    .map(|(name, k)| (name.clone(), k.channels())),
            )
            .collect()
    }

    /// Whether the current group's values are spectra (converted to RGB by the film in
    /// spectral mode, as Mitsuba's `aov` converts them): a nested integrator's radiance and
    /// the `albedo`; the geometric AOVs are numbers and are written as they are.
    pub fn outputs_spectrum(&self) -> bool {
        self.group < self.nested.len()
            || matches!(
                self.aovs.get(self.group - self.nested.len()),
                Some((_, AovKind::Albedo))
            )
    }

    pub fn li(
        &self,
        scene: &Scene,
        ray: Ray,
        wl: Vec4,
        sampler: &mut SampleStream,
        stats: &mut PathStats,
    ) -> Spectrum {
        if let Some((_, nested)) = self.nested.get(self.group) {
            return nested.li(scene, ray, wl, sampler, stats);
        }
        let Some((_, kind)) = self.aovs.get(self.group - self.nested.len()) else {
            return Spectrum::ZERO;
        };
        stats.rays += 1;
        let Some(si) = scene.intersect(&ray) else {
            return Spectrum::ZERO;
        };
        match kind {
            // Geometric AOVs: their three components as the (R, G, B) of a spectrum.
            AovKind::Depth => rgb(si.t * ray.d.length(), 0.0, 0.0),
            AovKind::Position => from_rgb(si.p + self.world_origin),
            AovKind::GeoNormal => from_rgb(si.ng),
            AovKind::ShNormal => from_rgb(si.frame.n),
            AovKind::Uv => rgb(si.uv.x, si.uv.y, 0.0),
            AovKind::Albedo => {
                let bsdf = scene.shading_bsdf(&si, wl);
                let wi = si.frame.to_local(-ray.d.normalize());
                bsdf.eval(wi, Vec3::Z) * std::f32::consts::PI
            }
        }
    }
}
