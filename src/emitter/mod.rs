//! Emitters. Sampling returns solid-angle densities so that next-event estimation and the MIS
//! weight of a BSDF-sampled hit use one and the same pdf. Delta emitters (point, spot,
//! projector, directional) return the probability 1 in place of a density and are never hit by rays;
//! environment emitters (constant, envmap) are seen by rays that leave the scene.

pub mod area;
pub mod constant;
pub mod directional;
pub mod envmap;
pub mod point;
pub mod projector;
pub mod spot;

pub use area::AreaEmitter;
pub use constant::ConstantEmitter;
pub use directional::DirectionalEmitter;
pub use envmap::EnvMapEmitter;
pub use point::PointEmitter;
pub use projector::ProjectorEmitter;
pub use spot::SpotEmitter;

use crate::geometry::{Frame, Ray};
use crate::sampling::square_to_uniform_disk_concentric;
use crate::shape::Shape;
use crate::simd::{for_each_lane, LaneF32, LaneMask, Lanes, Scalar, V3, V4};
use crate::spectrum::Spectrum;
use glam::{Vec2, Vec3, Vec4};

/// A ray leaving an emitter, for light tracing (Mitsuba's `Emitter::sample_ray`): the ray
/// and its weight, emitted radiance times the ray's measurement over its density (for a
/// ray drawn with density p(x, ω) in area and solid angle: L cos θ / p). The mean weight is
/// the emitted power.
#[derive(Clone, Copy, Debug)]
pub struct EmitterRay {
    pub ray: Ray,
    pub weight: Spectrum,
    /// Where the ray leaves the emitter, before any offset off its surface (on the disk
    /// of [`ray_from_infinity`] for emitters at infinity).
    pub origin: Vec3,
    /// The emitting side's unit normal at `origin` (the shading normal) and the geometric
    /// one; zero off surfaces (point sources, emitters at infinity).
    pub n: Vec3,
    pub ng: Vec3,
    /// The area density of `origin` on the emitter's surface (1 for point sources; for
    /// emitters at infinity the density 1/(π r²) of the disk).
    pub pdf_pos: f32,
}

impl EmitterRay {
    /// A ray leaving a point source (point, spot, projector).
    fn from_point(ray: Ray, weight: Spectrum) -> Self {
        EmitterRay {
            ray,
            weight,
            origin: ray.o,
            n: Vec3::ZERO,
            ng: Vec3::ZERO,
            pdf_pos: 1.0,
        }
    }

    /// A ray entering from infinity (directional, constant, envmap), its origin on a disk
    /// of area `disk`.
    fn from_infinity(ray: Ray, weight: Spectrum, disk: f32) -> Self {
        EmitterRay {
            ray,
            weight,
            origin: ray.o,
            n: Vec3::ZERO,
            ng: Vec3::ZERO,
            pdf_pos: 1.0 / disk,
        }
    }
}

/// A point drawn on an area emitter, for connecting the emitter itself to the camera.
#[derive(Clone, Copy, Debug)]
pub struct EmitterPosition {
    pub p: Vec3,
    pub p_error: Vec3,
    /// The emitting side's unit normal (the shading normal).
    pub n: Vec3,
    /// The geometric normal (offsets rays off the surface).
    pub ng: Vec3,
    /// Radiance leaving the front side at `p`.
    pub radiance: Spectrum,
    /// Area density of `p`.
    pub pdf: f32,
}

/// A ray entering the scene from infinity along unit direction `d`: it starts on the disk
/// of radius r perpendicular to `d`, tangent to the scene's bounding sphere (centre c,
/// radius r) on the side it comes from, at the point `u` picks uniformly (density 1/(π r²)).
fn ray_from_infinity(d: Vec3, u: Vec2, (c, r): (Vec3, f32)) -> Ray {
    let frame = Frame::from_normal(d);
    let q = square_to_uniform_disk_concentric(u) * r;
    Ray::new(c - d * r + frame.s * q.x + frame.t * q.y, d, f32::INFINITY)
}

/// A direction towards a sampled point on an emitter, as seen from a reference point.
#[derive(Clone, Copy, Debug)]
pub struct DirectionSample {
    /// The sampled point on the emitter, its error bound and unit normal (zero for delta
    /// and environment emitters; for those at infinity `p` is meaningless).
    pub p: Vec3,
    pub p_error: Vec3,
    pub n: Vec3,
    /// Unit direction from the reference point to `p`.
    pub d: Vec3,
    /// Distance from the reference point to `p` (∞ for emitters at infinity).
    pub dist: f32,
    /// Solid-angle density (including the probability of choosing this emitter once the
    /// scene has set it); for delta emitters the discrete probability instead.
    pub pdf: f32,
    /// Emitted radiance towards the reference point; for delta emitters the incident
    /// radiance's integral, intensity / dist² (point, spot) or irradiance (directional).
    pub radiance: Spectrum,
    /// The direction was the only possible one (no MIS: BSDF sampling cannot find it).
    pub delta: bool,
}

impl DirectionSample {
    /// Light from a point source (point, spot, projector) at `position`, seen along the unit
    /// direction `d` at distance `dist`: a delta sample with pdf 1.
    pub fn from_point(position: Vec3, d: Vec3, dist: f32, radiance: Spectrum) -> Self {
        DirectionSample {
            p: position,
            p_error: Vec3::ZERO,
            n: Vec3::ZERO,
            d,
            dist,
            pdf: 1.0,
            radiance,
            delta: true,
        }
    }

    /// The emitter lies at infinity (directional, environment): shadow rays go to ∞.
    pub fn is_infinite(&self) -> bool {
        self.dist.is_infinite()
    }
}

/// Direction samples, one per lane ([`DirectionSample`] in lanes).
#[derive(Clone, Copy, Debug)]
pub struct DirectionSamples<L: Lanes> {
    pub p: V3<L::F>,
    pub p_error: V3<L::F>,
    pub n: V3<L::F>,
    pub d: V3<L::F>,
    pub dist: L::F,
    pub pdf: L::F,
    pub radiance: V4<L::F>,
    pub delta: L::M,
}

impl<L: Lanes> DirectionSamples<L> {
    #[inline(always)]
    pub fn zero(l: L) -> Self {
        let z = l.splat(0.0);
        let v = V3::splat(z);
        DirectionSamples {
            p: v,
            p_error: v,
            n: v,
            d: v,
            dist: z,
            pdf: z,
            radiance: V4::splat(z),
            delta: l.mask(0),
        }
    }

    /// Lane `i` as a [`DirectionSample`].
    #[inline(always)]
    pub fn lane(&self, i: usize) -> DirectionSample {
        DirectionSample {
            p: self.p.lane(i),
            p_error: self.p_error.lane(i),
            n: self.n.lane(i),
            d: self.d.lane(i),
            dist: self.dist.lane(i),
            pdf: self.pdf.lane(i),
            radiance: self.radiance.lane(i),
            delta: self.delta.bits() >> i & 1 != 0,
        }
    }

    #[inline(always)]
    pub fn set_lane(&mut self, l: L, i: usize, ds: &DirectionSample) {
        self.p.set_lane(i, ds.p);
        self.p_error.set_lane(i, ds.p_error);
        self.n.set_lane(i, ds.n);
        self.d.set_lane(i, ds.d);
        self.dist.set_lane(i, ds.dist);
        self.pdf.set_lane(i, ds.pdf);
        self.radiance.set_lane(i, ds.radiance);
        let bit = l.mask(1 << i);
        self.delta = if ds.delta {
            self.delta | bit
        } else {
            self.delta.and_not(bit)
        };
    }

    /// `if m { a } else { b }` lane by lane.
    #[inline(always)]
    pub fn select(m: L::M, a: &Self, b: &Self) -> Self {
        DirectionSamples {
            p: V3::select(m, a.p, b.p),
            p_error: V3::select(m, a.p_error, b.p_error),
            n: V3::select(m, a.n, b.n),
            d: V3::select(m, a.d, b.d),
            dist: L::F::select(m, a.dist, b.dist),
            pdf: L::F::select(m, a.pdf, b.pdf),
            radiance: V4::select(m, a.radiance, b.radiance),
            delta: (m & a.delta) | b.delta.and_not(m),
        }
    }

    /// Emitters at infinity (directional, environment): `dist` is infinite.
    #[inline(always)]
    pub fn is_infinite(&self) -> L::M {
        !(self.dist.is_finite() | self.dist.is_nan())
    }
}

impl From<DirectionSample> for DirectionSamples<Scalar> {
    #[inline(always)]
    fn from(ds: DirectionSample) -> Self {
        DirectionSamples {
            p: ds.p.into(),
            p_error: ds.p_error.into(),
            n: ds.n.into(),
            d: ds.d.into(),
            dist: ds.dist,
            pdf: ds.pdf,
            radiance: ds.radiance.into(),
            delta: ds.delta,
        }
    }
}

#[derive(Clone, Debug)]
pub enum Emitter {
    Area(AreaEmitter),
    Point(PointEmitter),
    Spot(SpotEmitter),
    Projector(ProjectorEmitter),
    Directional(DirectionalEmitter),
    Constant(ConstantEmitter),
    EnvMap(EnvMapEmitter),
}

impl Emitter {
    /// The Mitsuba plugin name, for messages.
    pub fn plugin_name(&self) -> &'static str {
        match self {
            Emitter::Area(_) => "area",
            Emitter::Point(_) => "point",
            Emitter::Spot(_) => "spot",
            Emitter::Projector(_) => "projector",
            Emitter::Directional(_) => "directional",
            Emitter::Constant(_) => "constant",
            Emitter::EnvMap(_) => "envmap",
        }
    }

    /// Samples a direction from `p_ref` towards the emitter. The pdf does not include the
    /// probability of choosing this emitter.
    /// `wl`: the path's wavelengths (spectral mode; ignored in RGB mode).
    pub fn sample_direction(
        &self,
        p_ref: Vec3,
        u: Vec2,
        shapes: &[Shape],
        wl: Vec4,
    ) -> Option<DirectionSample> {
        match self {
            Emitter::Area(e) => e.sample_direction(p_ref, u, shapes, wl),
            Emitter::Point(e) => e.sample_direction(p_ref, wl),
            Emitter::Spot(e) => e.sample_direction(p_ref, wl),
            Emitter::Projector(e) => e.sample_direction(p_ref, wl),
            Emitter::Directional(e) => Some(e.sample_direction(wl)),
            Emitter::Constant(e) => e.sample_direction(u, wl),
            Emitter::EnvMap(e) => e.sample_direction(u, wl),
        }
    }

    /// [`Emitter::sample_direction`] lane by lane where `m` is set: the lane kernel of a
    /// constant area emitter on a mesh ([`AreaEmitter::sample_direction_lanes`]), every
    /// other emitter's scalar code lane by lane. The mask of the lanes that got a sample.
    #[inline(always)]
    pub fn sample_direction_lanes<L: Lanes>(
        &self,
        l: L,
        m: L::M,
        p_ref: V3<L::F>,
        u: (L::F, L::F),
        shapes: &[Shape],
        wl: &[Vec4],
    ) -> (L::M, DirectionSamples<L>) {
        if let Emitter::Area(e) = self {
            if let Some(r) = e.sample_direction_lanes(l, m, p_ref, u, shapes) {
                return r;
            }
        }
        let mut out = DirectionSamples::zero(l);
        let mut ok = 0u32;
        for_each_lane(
            L::WIDTH,
            m,
            #[inline(always)]
            |i| {
                let ui = Vec2::new(u.0.lane(i), u.1.lane(i));
                if let Some(ds) = self.sample_direction(p_ref.lane(i), ui, shapes, wl[i]) {
                    out.set_lane(l, i, &ds);
                    ok |= 1 << i;
                }
            },
        );
        (l.mask(ok), out)
    }

    /// A ray leaving the emitter, drawn from `u_pos` (its origin) and `u_dir` (its direction);
    /// emitters at infinity start their rays on a disk tangent to the scene's bounding
    /// sphere `bounds` (centre, radius). `None` when the sample carries no light.
    pub fn sample_ray(
        &self,
        u_pos: Vec2,
        u_dir: Vec2,
        shapes: &[Shape],
        bounds: (Vec3, f32),
        wl: Vec4,
    ) -> Option<EmitterRay> {
        let disk = std::f32::consts::PI * bounds.1 * bounds.1;
        let r = match self {
            Emitter::Area(e) => e.sample_ray(u_pos, u_dir, shapes, wl)?,
            Emitter::Point(e) => e.sample_ray(u_dir, wl),
            Emitter::Spot(e) => e.sample_ray(u_dir, wl)?,
            Emitter::Projector(e) => e.sample_ray(u_dir, wl)?,
            Emitter::Directional(e) => EmitterRay::from_infinity(
                ray_from_infinity(e.direction, u_pos, bounds),
                e.irradiance.eval(wl) * disk,
                disk,
            ),
            Emitter::Constant(e) => {
                let d = crate::sampling::square_to_uniform_sphere(u_dir);
                EmitterRay::from_infinity(
                    ray_from_infinity(-d, u_pos, bounds),
                    e.radiance.eval(wl) * (disk / constant::UNIFORM_SPHERE_PDF),
                    disk,
                )
            }
            Emitter::EnvMap(e) => {
                let ds = e.sample_direction(u_dir, wl)?;
                EmitterRay::from_infinity(
                    ray_from_infinity(-ds.d, u_pos, bounds),
                    ds.radiance * (disk / ds.pdf),
                    disk,
                )
            }
        };
        (r.weight.is_finite() && r.weight.max_element() > 0.0).then_some(r)
    }

    /// The solid-angle density with which [`Emitter::sample_ray`] takes direction `d` from
    /// its origin, whose emitting normal is `n` (area emitters: cosine-weighted about it);
    /// 0 for emitters at infinity, whose rays' origins are drawn instead (see
    /// [`EmitterRay::pdf_pos`]).
    pub fn pdf_ray_direction(&self, n: Vec3, d: Vec3) -> f32 {
        match self {
            Emitter::Area(_) => n.dot(d).max(0.0) * std::f32::consts::FRAC_1_PI,
            Emitter::Point(_) => constant::UNIFORM_SPHERE_PDF,
            Emitter::Spot(e) => e.pdf_ray_direction(d),
            Emitter::Projector(e) => e.pdf_ray_direction(d),
            Emitter::Directional(_) | Emitter::Constant(_) | Emitter::EnvMap(_) => 0.0,
        }
    }

    /// Whether the emitter lies at infinity (directional, constant, envmap).
    pub fn is_infinite(&self) -> bool {
        matches!(
            self,
            Emitter::Directional(_) | Emitter::Constant(_) | Emitter::EnvMap(_)
        )
    }

    /// A point on an area emitter (`None` for every other kind), for connecting the
    /// emitter to the camera.
    pub fn sample_position(&self, u: Vec2, shapes: &[Shape], wl: Vec4) -> Option<EmitterPosition> {
        match self {
            Emitter::Area(e) => e.sample_position(u, shapes, wl),
            _ => None,
        }
    }

    /// A Dirac delta in position or direction (point, spot, projector, directional): no
    /// camera ray or light-path connection can reach it.
    pub fn is_delta(&self) -> bool {
        matches!(
            self,
            Emitter::Point(_) | Emitter::Spot(_) | Emitter::Projector(_) | Emitter::Directional(_)
        )
    }

    /// An environment emitter: seen by rays that leave the scene.
    pub fn is_environment(&self) -> bool {
        matches!(self, Emitter::Constant(_) | Emitter::EnvMap(_))
    }

    /// Radiance arriving from infinity along −`d` (an escaping ray with direction `d`).
    pub fn eval_environment(&self, d: Vec3, wl: Vec4) -> Spectrum {
        match self {
            Emitter::Constant(e) => e.radiance.eval(wl),
            Emitter::EnvMap(e) => e.eval(d, wl),
            _ => Spectrum::ZERO,
        }
    }

    /// [`Emitter::eval_environment`] and [`Emitter::pdf_environment`] at once.
    pub fn eval_environment_with_pdf(&self, d: Vec3, wl: Vec4) -> (Spectrum, f32) {
        match self {
            Emitter::Constant(e) => (e.radiance.eval(wl), constant::UNIFORM_SPHERE_PDF),
            Emitter::EnvMap(e) => e.eval_with_pdf(d, wl),
            _ => (Spectrum::ZERO, 0.0),
        }
    }

    /// Solid-angle density with which `sample_direction` yields the escaping direction `d`.
    pub fn pdf_environment(&self, d: Vec3) -> f32 {
        match self {
            Emitter::Constant(_) => constant::UNIFORM_SPHERE_PDF,
            Emitter::EnvMap(e) => e.pdf_direction(d),
            _ => 0.0,
        }
    }

    /// Estimated emitted power (mean over the RGB channels), for choosing emitters in
    /// proportion to it (light tracing will; next-event estimation picks uniformly, as
    /// Mitsuba does). Emitters at infinity count what falls on the scene's bounding
    /// sphere of radius `scene_radius`:
    /// - area: π · A · L (one-sided Lambertian emitter)
    /// - point: 4π · I
    /// - spot: 2π (1 − cos θ) · I with θ halfway between beam_width and cutoff_angle (times
    ///   the texture's mean)
    /// - projector: π · mean irradiance · the image's area at distance 1 (Mitsuba's
    ///   `sample_ray` weight)
    /// - directional: π r² · E
    /// - constant and envmap: π · π r² · mean L (irradiance π L over the disk π r²)
    pub fn power(&self, shapes: &[Shape], scene_radius: f64) -> f64 {
        // (RGB mode's mean; spectral mode: the mean over the visible range, or for a D65
        // emission the RGB it was given, which is all a choice of emitter needs)
        let mean = |c: &crate::texture::ColorValue| c.mean_for_power();
        let disk = std::f64::consts::PI * scene_radius * scene_radius;
        match self {
            Emitter::Area(e) => {
                std::f64::consts::PI * shapes[e.shape as usize].geometry.area() * e.mean_radiance()
            }
            Emitter::Point(e) => 4.0 * std::f64::consts::PI * mean(&e.intensity),
            Emitter::Spot(e) => e.solid_angle() * mean(&e.intensity) * e.texture_mean(),
            Emitter::Projector(e) => std::f64::consts::PI * e.mean_irradiance() * e.image_area(),
            Emitter::Directional(e) => disk * mean(&e.irradiance),
            Emitter::Constant(e) => std::f64::consts::PI * disk * mean(&e.radiance),
            Emitter::EnvMap(e) => std::f64::consts::PI * disk * e.mean_radiance(),
        }
    }
}
