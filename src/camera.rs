//! Mitsuba's `perspective` sensor: a pinhole camera looking down its local +z axis, with
//! local +y up and local +x to the *left* of the image (Mitsuba's convention, so that
//! `lookat` cameras are not mirrored). Film position (0,0) is the top-left corner.
//!
//! Mitsuba's `thinlens` sensor is the same camera with a thin lens (Kolb, Mitchell and
//! Hanrahan 1995; pbrt-v4 §5.2.3): rays start at a point sampled uniformly on the aperture
//! disk of radius `aperture_radius` (concentric map) in the local z = 0 plane and pass
//! through the point that the pinhole ray meets on the plane of focus z = `focus_distance`,
//! which is therefore imaged sharply.
//!
//! Mitsuba's `orthographic` sensor is [`OrthographicCamera`]; [`Camera`] holds either kind.
//!
//! Film positions handed to the cameras are relative to the rendered window ([`FilmWindow`]):
//! Mitsuba's crop window of the film (`crop_offset_x`/`_y`, `crop_width`/`_height`) and the
//! perspective sensor's principal point shift (`principal_point_offset_x`/`_y`). Without them
//! the window is the whole film and every position maps to itself.

use crate::geometry::Ray;
use crate::sampling::square_to_uniform_disk_concentric;
use glam::{DMat4, DVec2, DVec3, Vec2, Vec3};

/// Which image axis `fov` spans (Mitsuba's `fov_axis`).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum FovAxis {
    X,
    Y,
    Diagonal,
    Smaller,
    Larger,
}

/// Converts a field of view (degrees) along `axis` into the horizontal field of view, as
/// Mitsuba does for an image of aspect ratio `aspect` = width / height.
pub fn fov_x_degrees(fov: f64, axis: FovAxis, aspect: f64) -> f64 {
    let to_x = |tan_half: f64| 2.0 * tan_half.atan().to_degrees();
    let tan_half = (fov.to_radians() * 0.5).tan();
    match axis {
        FovAxis::X => fov,
        FovAxis::Y => to_x(tan_half * aspect),
        FovAxis::Diagonal => to_x(tan_half * aspect / (aspect * aspect + 1.0).sqrt()),
        FovAxis::Smaller => {
            if aspect > 1.0 {
                to_x(tan_half * aspect)
            } else {
                fov
            }
        }
        FovAxis::Larger => {
            if aspect > 1.0 {
                fov
            } else {
                to_x(tan_half * aspect)
            }
        }
    }
}

/// The rendered part of the film (Mitsuba's crop window) and the principal point's shift,
/// in fractions of the whole film (x right, y down).
///
/// A position `s` ∈ [0,1]² of the window is the position `offset + scale · s + shift` of the
/// whole film, as in Mitsuba's `perspective_projection` (crop) and `sample_ray` (principal
/// point: `principal_point_offset` is added to the position in units of the whole film).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct FilmWindow {
    /// `crop_offset / size`.
    pub offset: DVec2,
    /// `crop_size / size`.
    pub scale: DVec2,
    /// `principal_point_offset` (perspective sensors only; zero elsewhere).
    pub shift: DVec2,
}

impl FilmWindow {
    /// The whole film, no shift: every position maps to itself, bit for bit.
    pub const FULL: FilmWindow = FilmWindow {
        offset: DVec2::ZERO,
        scale: DVec2::ONE,
        shift: DVec2::ZERO,
    };

    /// The window of `crop_size` pixels at `crop_offset` of a film of `size` pixels, with
    /// the principal point shifted by `shift` (fractions of the film).
    pub fn new(
        size: (u32, u32),
        crop_offset: (u32, u32),
        crop_size: (u32, u32),
        shift: DVec2,
    ) -> Self {
        let size = DVec2::new(size.0 as f64, size.1 as f64);
        FilmWindow {
            offset: DVec2::new(crop_offset.0 as f64, crop_offset.1 as f64) / size,
            scale: DVec2::new(crop_size.0 as f64, crop_size.1 as f64) / size,
            shift,
        }
    }

    /// The position on the whole film of window position `s`.
    pub fn to_film(&self, s: Vec2) -> DVec2 {
        self.offset + self.scale * s.as_dvec2() + self.shift
    }

    /// The window position of film position `f` (the inverse of [`FilmWindow::to_film`]).
    pub fn from_film(&self, f: DVec2) -> DVec2 {
        (f - self.shift - self.offset) / self.scale
    }

    /// The window's share of the film's area.
    pub fn area_fraction(&self) -> f64 {
        self.scale.x * self.scale.y
    }
}

#[derive(Clone, Debug)]
pub struct PerspectiveCamera {
    origin: Vec3,
    /// Camera-to-world linear part (columns: left, up, forward).
    x: Vec3,
    y: Vec3,
    z: Vec3,
    tan_half_x: f64,
    aspect: f64,
    near_clip: f32,
    far_clip: f32,
    /// The thin lens, if any (`None`: pinhole).
    lens: Option<ThinLens>,
    /// World to camera space (the inverse of `to_world`), for connecting points to the
    /// pinhole ([`PerspectiveCamera::sample_direction`]).
    to_local: DMat4,
    /// The rendered window of the film.
    window: FilmWindow,
}

/// A connection from a point in the scene to the camera's pinhole (Mitsuba's
/// `Sensor::sample_direction`), for light tracing.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct SensorSample {
    /// Where the point appears on the film, in [0,1]² (x right, y down).
    pub film: Vec2,
    /// The pinhole's position.
    pub p: Vec3,
    /// Unit direction from the point to the pinhole.
    pub d: Vec3,
    /// Distance from the point to the pinhole.
    pub dist: f32,
    /// The importance arriving at the point: W_e / dist², with W_e the pinhole's directional
    /// response (see [`PerspectiveCamera::sample_direction`]).
    pub weight: f32,
}

/// Aperture and focus of a `thinlens` sensor.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct ThinLens {
    pub aperture_radius: f64,
    pub focus_distance: f64,
}

impl PerspectiveCamera {
    /// `fov_x` in degrees, in (0, 180); `aspect` = width / height.
    pub fn new(to_world: DMat4, fov_x: f64, aspect: f64, near_clip: f64, far_clip: f64) -> Self {
        let col = |i: usize| to_world.col(i).truncate();
        PerspectiveCamera {
            origin: to_world.transform_point3(DVec3::ZERO).as_vec3(),
            x: col(0).as_vec3(),
            y: col(1).as_vec3(),
            z: col(2).as_vec3(),
            tan_half_x: (fov_x.to_radians() * 0.5).tan(),
            aspect,
            near_clip: near_clip as f32,
            far_clip: far_clip as f32,
            lens: None,
            to_local: to_world.inverse(),
            window: FilmWindow::FULL,
        }
    }

    /// The same camera rendering `window` of its film (crop window, principal point).
    pub fn with_window(mut self, window: FilmWindow) -> Self {
        self.window = window;
        self
    }

    /// The same camera with a thin lens (Mitsuba's `thinlens`).
    pub fn with_thin_lens(mut self, lens: ThinLens) -> Self {
        self.lens = Some(lens);
        self
    }

    /// Whether rays need an aperture sample (Mitsuba's `needs_aperture_sample`): the sampler
    /// then draws it right after the pixel position.
    pub fn needs_aperture_sample(&self) -> bool {
        self.lens.is_some()
    }

    /// The primary ray through film position `s` ∈ [0,1]² and, for a thin lens, the aperture
    /// sample `u` ∈ [0,1)² (ignored by a pinhole). Starts on the near clipping plane and ends
    /// on the far one (measured along the local z axis), as in Mitsuba.
    pub fn generate_ray_lens(&self, s: Vec2, u: Vec2) -> Ray {
        let Some(lens) = self.lens else {
            return self.generate_ray(s);
        };
        let f = self.window.to_film(s);
        let x = (1.0 - 2.0 * f.x) * self.tan_half_x;
        let y = (1.0 - 2.0 * f.y) * self.tan_half_x / self.aspect;
        // The pinhole ray meets the plane of focus at (x, y, 1) · focus_distance.
        let focus = DVec3::new(x, y, 1.0) * lens.focus_distance;
        let a = square_to_uniform_disk_concentric(u).as_dvec2() * lens.aperture_radius;
        let o_local = DVec3::new(a.x, a.y, 0.0);
        let d_local = (focus - o_local).normalize();
        let inv_z = 1.0 / d_local.z;
        let near_t = self.near_clip as f64 * inv_z;
        let far_t = self.far_clip as f64 * inv_z;
        let (xa, ya, za) = (self.x.as_dvec3(), self.y.as_dvec3(), self.z.as_dvec3());
        let o = self.origin.as_dvec3() + xa * o_local.x + ya * o_local.y;
        let d = (xa * d_local.x + ya * d_local.y + za * d_local.z).normalize();
        Ray::new(
            (o + d * near_t).as_vec3(),
            d.as_vec3(),
            (far_t - near_t) as f32,
        )
    }

    /// Connects the point `p` to the pinhole (Mitsuba's `sample_direction` of the perspective
    /// sensor): `None` when `p` lies outside the image or the clipping range (measured along
    /// the local z axis) or the camera has a thin lens.
    ///
    /// The importance W_e is the pinhole's response normalised so that it integrates to 1
    /// over the image: a film position drawn uniformly on the image rectangle at distance 1,
    /// of area A = (2 tan(fov_x/2))² / aspect, has the solid-angle density 1 / (A cos³θ), θ
    /// the angle to the optical axis, so W_e(ω) = 1 / (A cos³θ) (Veach 1997, §10.2; pbrt-v4
    /// §5.4.1). A path vertex that sees the pinhole contributes W_e / dist² times what
    /// arrives there to the pixel it lands in, per sample of the whole image.
    pub fn sample_direction(&self, p: Vec3) -> Option<SensorSample> {
        if self.lens.is_some() {
            return None;
        }
        self.connect(p, Vec2::ZERO, DVec2::ZERO)
    }

    /// Connects the point `p` to a point of the lens drawn uniformly from `u` (the pinhole
    /// itself without a lens), for film positions within the window enlarged by `margin`
    /// (fractions of the window on each side: the pixels sampled beyond it with Mitsuba's
    /// `sample_border`), whose area the importance is normalised over.
    ///
    /// A thin lens images the point through the lens point a where the ray from a through p
    /// meets the plane of focus: the film position whose pinhole ray passes there. With the
    /// lens point drawn uniformly (density 1/(π r²), as camera rays draw it), the film
    /// position uniformly on the image rectangle at distance 1 (area A) and θ the angle of
    /// the ray a → p to the axis, a camera ray from a has the solid-angle density
    /// 1 / (A cos³θ) (the focus plane at distance f is the image rectangle scaled by f, seen
    /// from a at distance f / cos θ), the same as the pinhole's: so the weight is the
    /// pinhole's W_e / dist² with θ and dist measured from a.
    pub fn connect(&self, p: Vec3, u: Vec2, margin: DVec2) -> Option<SensorSample> {
        let local = self.to_local.transform_point3(p.as_dvec3());
        if !(local.z >= self.near_clip as f64 && local.z <= self.far_clip as f64) {
            return None;
        }
        // The lens point (local) and where the ray from it through p meets the plane of
        // focus, in units of the focus distance: the pinhole ray's (x, y, 1).
        let (a, x, y) = match self.lens {
            None => (DVec3::ZERO, local.x / local.z, local.y / local.z),
            Some(lens) => {
                let d = square_to_uniform_disk_concentric(u).as_dvec2() * lens.aperture_radius;
                let a = DVec3::new(d.x, d.y, 0.0);
                let t = lens.focus_distance / local.z;
                let q = a + (local - a) * t;
                (a, q.x / lens.focus_distance, q.y / lens.focus_distance)
            }
        };
        let film = self.window.from_film(DVec2::new(
            0.5 * (1.0 - x / self.tan_half_x),
            0.5 * (1.0 - y * self.aspect / self.tan_half_x),
        ));
        if !(film.cmpge(-margin).all() && film.cmple(DVec2::ONE + margin).all()) {
            return None;
        }
        let v = local - a;
        let dist = v.length();
        if !(dist > 0.0 && dist.is_finite()) {
            return None;
        }
        let cos = v.z / dist;
        let we = 1.0 / (self.importance_area(margin) * cos * cos * cos);
        let (xa, ya) = (self.x.as_dvec3(), self.y.as_dvec3());
        let lens_point = self.origin.as_dvec3() + xa * a.x + ya * a.y;
        let d = lens_point - p.as_dvec3();
        let world_dist = d.length();
        if !(world_dist > 0.0 && world_dist.is_finite()) {
            return None;
        }
        Some(SensorSample {
            film: film.as_vec2(),
            p: lens_point.as_vec3(),
            d: (d / world_dist).as_vec3(),
            dist: world_dist as f32,
            weight: (we / (world_dist * world_dist)) as f32,
        })
    }

    /// The area A at distance 1 of the part of the image plane that camera rays sample:
    /// the window (Mitsuba's `m_image_rect` is the crop's) enlarged by `margin` on each side.
    fn importance_area(&self, margin: DVec2) -> f64 {
        let grow = (1.0 + 2.0 * margin.x) * (1.0 + 2.0 * margin.y);
        4.0 * self.tan_half_x * self.tan_half_x / self.aspect * self.window.area_fraction() * grow
    }

    /// The solid-angle density with which camera rays (from the lens point they start at)
    /// take the world direction `d`: 1 / (A cos³θ) over the sampled image plane (see
    /// [`PerspectiveCamera::connect`]; 0 behind the camera). Rays through the window only,
    /// so the caller knows that `d` lies in it.
    pub fn pdf_direction(&self, d: Vec3, margin: DVec2) -> f32 {
        let l = self.to_local.transform_vector3(d.as_dvec3());
        let len = l.length();
        if !(l.z > 0.0 && len > 0.0) {
            return 0.0;
        }
        let cos = l.z / len;
        (1.0 / (self.importance_area(margin) * cos * cos * cos)) as f32
    }

    /// Where a camera ray starts on the lens (the pinhole, or the aperture point), before
    /// its move to the near clipping plane: `ray` as [`PerspectiveCamera::generate_ray_lens`]
    /// made it.
    pub fn lens_point(&self, ray: &Ray) -> Vec3 {
        let dz = self.to_local.transform_vector3(ray.d.as_dvec3()).z;
        if self.lens.is_none() || dz <= 0.0 {
            return self.origin;
        }
        (ray.o.as_dvec3() - ray.d.as_dvec3() * (self.near_clip as f64 / dz)).as_vec3()
    }

    /// The local (camera-space) unit direction through film position `s` ∈ [0,1]².
    pub fn local_direction(&self, s: Vec2) -> Vec3 {
        let f = self.window.to_film(s);
        let x = (1.0 - 2.0 * f.x) * self.tan_half_x;
        let y = (1.0 - 2.0 * f.y) * self.tan_half_x / self.aspect;
        DVec3::new(x, y, 1.0).normalize().as_vec3()
    }

    /// The primary ray through film position `s` ∈ [0,1]² (x right, y down). It starts on
    /// the near clipping plane and ends on the far one, as in Mitsuba.
    pub fn generate_ray(&self, s: Vec2) -> Ray {
        let local = self.local_direction(s);
        let inv_z = 1.0 / local.z;
        let near_t = self.near_clip * inv_z;
        let far_t = self.far_clip * inv_z;
        let d = (self.x * local.x + self.y * local.y + self.z * local.z).normalize();
        Ray::new(self.origin + d * near_t, d, far_t - near_t)
    }
}

/// Mitsuba's `orthographic` sensor (src/sensors/orthographic.cpp): parallel rays along the
/// local +z axis, from a film rectangle in the local z = `near_clip` plane.
///
/// Mitsuba's conventions, checked against Mitsuba 3.9.1 with
/// validation/mitsuba/orthographic_rays.py:
/// - Film position `s` ∈ [0,1]² (x right, y down; (0,0) the top-left corner) maps to the local
///   point (1 − 2 s.x, (1 − 2 s.y) / aspect, near_clip), aspect = width / height. So local x
///   always spans [−1, 1], and local y spans [−1/aspect, 1/aspect] whatever the film's
///   orientation (a 200x120 film spans y ∈ [−0.6, 0.6], a portrait film more than [−1, 1]).
///   Local +x is to the *left* of the image and +y up, as for [`PerspectiveCamera`]. The
///   image's size in the world comes from `to_world`, typically a `<scale x= y=>` before the
///   `<lookat>`.
/// - The ray starts at `to_world` applied to that point, on the near plane, with direction
///   `to_world · (0,0,1)` normalised, and `tmax = far_clip − near_clip`. (With a scale along
///   local z in `to_world` the near plane moves to scale · near_clip in the world while tmax
///   stays far − near, as in Mitsuba.)
/// - Defaults near_clip 0.01, far_clip 1e4 (as for `perspective`); no aperture sample.
#[derive(Clone, Debug)]
pub struct OrthographicCamera {
    /// `to_world · (0, 0, near_clip)`: the centre of the film rectangle.
    centre: DVec3,
    /// `to_world · e_x` and `to_world · e_y`: the local x and y axes in the world.
    x: DVec3,
    y: DVec3,
    /// Unit viewing direction.
    d: Vec3,
    aspect: f64,
    tmax: f32,
    /// The rendered window of the film (crop window; no principal point shift).
    window: FilmWindow,
}

impl OrthographicCamera {
    /// `aspect` = film width / height; `near_clip` < `far_clip` (both positive in Mitsuba).
    pub fn new(to_world: DMat4, aspect: f64, near_clip: f64, far_clip: f64) -> Self {
        // Mitsuba stores the clip distances as f32 and subtracts them in f32.
        let (near32, far32) = (near_clip as f32, far_clip as f32);
        OrthographicCamera {
            centre: to_world.transform_point3(DVec3::new(0.0, 0.0, near32 as f64)),
            x: to_world.transform_vector3(DVec3::X),
            y: to_world.transform_vector3(DVec3::Y),
            d: to_world.transform_vector3(DVec3::Z).normalize().as_vec3(),
            aspect,
            tmax: far32 - near32,
            window: FilmWindow::FULL,
        }
    }

    /// The same camera rendering `window` of its film (crop window).
    pub fn with_window(mut self, window: FilmWindow) -> Self {
        self.window = window;
        self
    }

    /// Always false: an orthographic camera has no aperture.
    pub fn needs_aperture_sample(&self) -> bool {
        false
    }

    /// The primary ray through film position `s` ∈ [0,1]² (x right, y down).
    pub fn generate_ray(&self, s: Vec2) -> Ray {
        let f = self.window.to_film(s);
        let lx = 1.0 - 2.0 * f.x;
        let ly = (1.0 - 2.0 * f.y) / self.aspect;
        let o = self.centre + self.x * lx + self.y * ly;
        Ray::new(o.as_vec3(), self.d, self.tmax)
    }

    /// The same as [`OrthographicCamera::generate_ray`]: the aperture sample is ignored.
    pub fn generate_ray_lens(&self, s: Vec2, _u: Vec2) -> Ray {
        self.generate_ray(s)
    }
}

/// The scene's sensor: one of Mitsuba's projective cameras, with the methods the renderer
/// needs dispatched to it.
#[derive(Clone, Debug)]
pub enum Camera {
    /// `perspective` or `thinlens`.
    Perspective(PerspectiveCamera),
    /// `orthographic`.
    Orthographic(OrthographicCamera),
}

impl From<PerspectiveCamera> for Camera {
    fn from(c: PerspectiveCamera) -> Self {
        Camera::Perspective(c)
    }
}

impl From<OrthographicCamera> for Camera {
    fn from(c: OrthographicCamera) -> Self {
        Camera::Orthographic(c)
    }
}

impl Camera {
    /// Whether rays need an aperture sample, drawn right after the pixel position.
    pub fn needs_aperture_sample(&self) -> bool {
        match self {
            Camera::Perspective(c) => c.needs_aperture_sample(),
            Camera::Orthographic(c) => c.needs_aperture_sample(),
        }
    }

    /// The primary ray through film position `s` ∈ [0,1]² (x right, y down), without an
    /// aperture sample.
    pub fn generate_ray(&self, s: Vec2) -> Ray {
        match self {
            Camera::Perspective(c) => c.generate_ray(s),
            Camera::Orthographic(c) => c.generate_ray(s),
        }
    }

    /// Connects the point `p` to the camera for light tracing; only the pinhole
    /// `perspective` camera can (see [`Camera::supports_light_tracing`]).
    pub fn sample_direction(&self, p: Vec3) -> Option<SensorSample> {
        match self {
            Camera::Perspective(c) => c.sample_direction(p),
            Camera::Orthographic(_) => None,
        }
    }

    /// Connects the point `p` to the camera through the lens point drawn from `u`, for
    /// film positions within the window enlarged by `margin` on each side
    /// ([`PerspectiveCamera::connect`]): a pinhole or thin-lens `perspective` camera; `None`
    /// for an orthographic one (its rays are parallel: no point connects to it).
    pub fn connect(&self, p: Vec3, u: Vec2, margin: DVec2) -> Option<SensorSample> {
        match self {
            Camera::Perspective(c) => c.connect(p, u, margin),
            Camera::Orthographic(_) => None,
        }
    }

    /// Whether [`Camera::connect`] can reach this camera (perspective, with or without a
    /// lens).
    pub fn connects(&self) -> bool {
        matches!(self, Camera::Perspective(_))
    }

    /// The solid-angle density with which camera rays take direction `d`
    /// ([`PerspectiveCamera::pdf_direction`]; 0 for an orthographic camera, whose direction
    /// is fixed).
    pub fn pdf_direction(&self, d: Vec3, margin: DVec2) -> f32 {
        match self {
            Camera::Perspective(c) => c.pdf_direction(d, margin),
            Camera::Orthographic(_) => 0.0,
        }
    }

    /// Where camera ray `ray` starts on the lens (the pinhole, or the aperture point; for an
    /// orthographic camera the ray's origin on the film rectangle).
    pub fn lens_point(&self, ray: &Ray) -> Vec3 {
        match self {
            Camera::Perspective(c) => c.lens_point(ray),
            Camera::Orthographic(_) => ray.o,
        }
    }

    /// The pinhole's position (the film centre for an orthographic camera).
    pub fn position(&self) -> Vec3 {
        match self {
            Camera::Perspective(c) => c.origin,
            Camera::Orthographic(c) => c.centre.as_vec3(),
        }
    }

    /// Whether light tracing can connect to this camera: a pinhole `perspective` one (a thin
    /// lens or an orthographic camera would need an aperture or film-plane sample).
    pub fn supports_light_tracing(&self) -> bool {
        matches!(self, Camera::Perspective(c) if c.lens.is_none())
    }

    /// The primary ray through film position `s` with aperture sample `u` ∈ [0,1)² (used
    /// only by a thin lens).
    pub fn generate_ray_lens(&self, s: Vec2, u: Vec2) -> Ray {
        match self {
            Camera::Perspective(c) => c.generate_ray_lens(s, u),
            Camera::Orthographic(c) => c.generate_ray_lens(s, u),
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn look(origin: DVec3, target: DVec3, up: DVec3) -> DMat4 {
        let dir = (target - origin).normalize();
        let left = up.cross(dir).normalize();
        let new_up = dir.cross(left);
        DMat4::from_cols(
            left.extend(0.0),
            new_up.extend(0.0),
            dir.extend(0.0),
            origin.extend(1.0),
        )
    }

    /// A point on the camera ray through film position s projects back to s, and the
    /// direction to the pinhole is the ray's reversed (light tracing meets the camera where
    /// camera rays leave it).
    #[test]
    fn sample_direction_inverts_generate_ray() {
        let m = look(
            DVec3::new(1.0, 2.0, 3.0),
            DVec3::new(-2.0, 0.5, -4.0),
            DVec3::new(0.1, 1.0, 0.0),
        );
        let cam = PerspectiveCamera::new(m, 65.0, 1.6, 1e-2, 1e4);
        for (i, s) in [
            (0.5, 0.5),
            (0.01, 0.02),
            (0.99, 0.5),
            (0.3, 0.97),
            (0.75, 0.25),
        ]
        .into_iter()
        .enumerate()
        {
            let s = Vec2::new(s.0, s.1);
            let ray = cam.generate_ray(s);
            let p = ray.at(0.5 + 3.0 * i as f32);
            let c = cam.sample_direction(p).expect("inside the image");
            assert!((c.film - s).abs().max_element() < 1e-5, "{} vs {s}", c.film);
            assert!((c.d + ray.d).length() < 1e-5);
            assert!((c.p - c.d * c.dist - p).length() < 1e-4);
        }
        // Behind the camera, outside the frustum, nearer than the near clip: no connection.
        let o = DVec3::new(1.0, 2.0, 3.0).as_vec3();
        let fwd = (DVec3::new(-3.0, -1.5, -7.0).normalize()).as_vec3();
        assert!(cam.sample_direction(o - fwd).is_none());
        assert!(cam.sample_direction(o + fwd * 0.005).is_none());
        assert!(cam
            .sample_direction(o + fwd + Vec3::new(0.0, 5.0, 0.0))
            .is_none());
        // A thin lens cannot be connected to by a point.
        let lens = cam.clone().with_thin_lens(ThinLens {
            aperture_radius: 0.1,
            focus_distance: 2.0,
        });
        assert!(lens.sample_direction(o + fwd).is_none());
    }

    /// W_e integrates to 1 over the image's solid angle: a midpoint-rule sum over the
    /// sphere of directions (1200 x 2400 cells), independent of the film mapping used to
    /// derive W_e. A pixel then receives 1/(width·height) of a uniform unit radiance field's
    /// importance, which is what makes a light-traced image equal a camera-traced one.
    #[test]
    fn importance_integrates_to_one_over_the_image() {
        for (fov, aspect) in [(40.0, 1.0), (70.0, 8.0), (100.0, 0.5)] {
            let m = look(DVec3::ZERO, DVec3::new(0.0, 0.0, 1.0), DVec3::Y);
            let cam = PerspectiveCamera::new(m, fov, aspect, 1e-2, 1e4);
            let (nt, np) = (1200, 2400);
            let (dt, dp) = (
                std::f64::consts::PI / nt as f64,
                2.0 * std::f64::consts::PI / np as f64,
            );
            let mut sum = 0.0;
            for i in 0..nt / 2 {
                let theta = (i as f64 + 0.5) * dt;
                for j in 0..np {
                    let phi = (j as f64 + 0.5) * dp;
                    let d = DVec3::new(
                        theta.sin() * phi.cos(),
                        theta.sin() * phi.sin(),
                        theta.cos(),
                    );
                    if let Some(c) = cam.sample_direction((d * 10.0).as_vec3()) {
                        sum += c.weight as f64 * 100.0 * theta.sin() * dt * dp;
                    }
                }
            }
            assert!(
                (sum - 1.0).abs() < 2e-3,
                "fov {fov}, aspect {aspect}: {sum}"
            );
        }
    }

    #[test]
    fn corners_and_centre_for_each_fov_axis() {
        // 200x100 image (aspect 2), camera at the origin looking down -z with +y up.
        let m = look(DVec3::ZERO, DVec3::new(0.0, 0.0, -1.0), DVec3::Y);
        let aspect = 2.0;
        let centre_dir = |fov_x| {
            PerspectiveCamera::new(m, fov_x, aspect, 1e-2, 1e4)
                .generate_ray(Vec2::splat(0.5))
                .d
        };
        assert!((centre_dir(90.0) - Vec3::new(0.0, 0.0, -1.0)).length() < 1e-6);
        for (axis, fov, tan_x, tan_y) in [
            (FovAxis::X, 90.0, 1.0, 0.5),
            (FovAxis::Y, 90.0, 2.0, 1.0),
            (FovAxis::Smaller, 90.0, 2.0, 1.0),
            (FovAxis::Larger, 90.0, 1.0, 0.5),
            (
                FovAxis::Diagonal,
                90.0,
                2.0 / 5f64.sqrt(),
                1.0 / 5f64.sqrt(),
            ),
        ] {
            let cam =
                PerspectiveCamera::new(m, fov_x_degrees(fov, axis, aspect), aspect, 1e-2, 1e4);
            // top-left corner of the image: left (-x world, since the camera looks down -z
            // with left = +x local = up × dir = -x world... ) and up.
            let r = cam.generate_ray(Vec2::ZERO);
            let d = r.d / -r.d.z;
            assert!((d.x as f64 + tan_x).abs() < 1e-5, "{axis:?}: {d}");
            assert!((d.y as f64 - tan_y).abs() < 1e-5, "{axis:?}: {d}");
            let r = cam.generate_ray(Vec2::ONE);
            let d = r.d / -r.d.z;
            assert!((d.x as f64 - tan_x).abs() < 1e-5 && (d.y as f64 + tan_y).abs() < 1e-5);
        }
    }

    #[test]
    fn ray_starts_on_near_plane_and_ends_on_far_plane() {
        let m = look(DVec3::new(0.0, 0.0, 5.0), DVec3::ZERO, DVec3::Y);
        let cam = PerspectiveCamera::new(m, 60.0, 1.0, 0.5, 100.0);
        let r = cam.generate_ray(Vec2::new(0.1, 0.8));
        let start_depth = (5.0 - r.o.z) as f64;
        let end_depth = (5.0 - r.at(r.tmax).z) as f64;
        assert!((start_depth - 0.5).abs() < 1e-5 && (end_depth - 100.0).abs() < 1e-3);
    }

    /// Mitsuba 3.9.1's orthographic rays, from validation/mitsuba/orthographic_rays.py.
    const MITSUBA_ORTHO: &str = include_str!("../tests/data/mitsuba_orthographic_rays.txt");

    struct OrthoCase {
        name: String,
        aspect: f64,
        near: f64,
        far: f64,
        /// The `<transform name="to_world">` operations, as in the scene file.
        ops: String,
        /// Mitsuba's composed to_world.
        to_world: DMat4,
        /// (s, o, d, tmax)
        rays: Vec<(Vec2, Vec3, Vec3, f32)>,
    }

    fn ortho_cases() -> Vec<OrthoCase> {
        let nums =
            |s: &str| -> Vec<f64> { s.split_whitespace().map(|x| x.parse().unwrap()).collect() };
        let mut cases: Vec<OrthoCase> = Vec::new();
        for line in MITSUBA_ORTHO.lines().filter(|l| !l.starts_with('#')) {
            let (tag, rest) = line.split_once(' ').unwrap();
            match tag {
                "case" => {
                    let (name, rest) = rest.split_once(' ').unwrap();
                    let v = nums(rest);
                    cases.push(OrthoCase {
                        name: name.to_string(),
                        aspect: v[0] / v[1],
                        near: v[2],
                        far: v[3],
                        ops: String::new(),
                        to_world: DMat4::IDENTITY,
                        rays: Vec::new(),
                    });
                }
                "xml" => cases.last_mut().unwrap().ops = rest.to_string(),
                "to_world" => {
                    let v: [f64; 16] = nums(rest).try_into().unwrap();
                    cases.last_mut().unwrap().to_world = DMat4::from_cols_array(&v).transpose();
                }
                "r" => {
                    let v: Vec<f32> = nums(rest).iter().map(|&x| x as f32).collect();
                    cases.last_mut().unwrap().rays.push((
                        Vec2::new(v[0], v[1]),
                        Vec3::from_slice(&v[2..5]),
                        Vec3::from_slice(&v[5..8]),
                        v[8],
                    ));
                }
                _ => panic!("bad line {line}"),
            }
        }
        assert_eq!(cases.len(), 3);
        cases
    }

    /// The to_world that penumbra's XML parser composes from `ops`.
    fn parsed_to_world(ops: &str) -> DMat4 {
        use crate::scene::xml::{load_str, Value};
        let xml = format!(
            "<scene version=\"3.0.0\"><sensor type=\"orthographic\">\
             <transform name=\"to_world\">{ops}</transform></sensor></scene>"
        );
        let root = load_str(&xml, std::path::Path::new("inline.xml"), &[])
            .unwrap()
            .root;
        let sensor = &root.children[0].object;
        match &sensor
            .properties
            .iter()
            .find(|p| p.name == "to_world")
            .unwrap()
            .value
        {
            Value::Transform(m) => *m,
            other => panic!("not a transform: {other:?}"),
        }
    }

    #[test]
    fn orthographic_rays_match_mitsuba() {
        for c in ortho_cases() {
            // penumbra's parser composes the XML operations as Mitsuba does (each one applied
            // after the previous: lookat · scale for the suite's scene).
            let m = parsed_to_world(&c.ops);
            let scale = c
                .to_world
                .to_cols_array()
                .iter()
                .fold(1.0f64, |a, x| a.max(x.abs()));
            let diff = (m - c.to_world)
                .to_cols_array()
                .iter()
                .fold(0.0f64, |a, x| a.max(x.abs()));
            assert!(diff < 1e-6 * scale, "{}: to_world off by {diff}", c.name);
            let cam = Camera::from(OrthographicCamera::new(m, c.aspect, c.near, c.far));
            assert!(!cam.needs_aperture_sample());
            for (s, o, d, tmax) in &c.rays {
                // Mitsuba composes and applies to_world in f32: errors of a few ULPs of the
                // largest term (|to_world| entries ~3, translations ~5), ~2e-7 relative (the
                // largest seen); 2e-6 of the point's scale leaves a 10x margin.
                let r = cam.generate_ray_lens(*s, Vec2::new(0.3, 0.7));
                let oscale = o.abs().max_element().max(scale as f32);
                assert!(
                    (r.o - *o).abs().max_element() <= 2e-6 * oscale,
                    "{} at {s}: o {} vs {o}",
                    c.name,
                    r.o
                );
                assert!(
                    (r.d - *d).abs().max_element() <= 1e-6,
                    "{} at {s}: d {} vs {d}",
                    c.name,
                    r.d
                );
                assert_eq!(r.tmax, *tmax, "{}: tmax", c.name);
                let r2 = cam.generate_ray(*s);
                assert_eq!((r2.o, r2.d, r2.tmax), (r.o, r.d, r.tmax));
            }
        }
    }

    #[test]
    fn orthographic_film_rectangle_and_clip_planes() {
        // Looking down -z from z = 10, up +y, a 2x (world) scale, 200x120 film (aspect 5/3).
        let m = look(DVec3::new(0.0, 0.0, 10.0), DVec3::ZERO, DVec3::Y)
            * DMat4::from_scale(DVec3::new(2.0, 2.0, 1.0));
        let cam = OrthographicCamera::new(m, 200.0 / 120.0, 0.5, 30.0);
        assert!(!cam.needs_aperture_sample());
        // Top-left of the image is local +x (left) = up × dir = +y × −z = world −x, and +y;
        // half extents 2 and 2 / aspect = 1.2.
        let tl = cam.generate_ray(Vec2::ZERO);
        assert!(
            (tl.o - Vec3::new(-2.0, 1.2, 9.5)).length() < 1e-6,
            "{}",
            tl.o
        );
        let br = cam.generate_ray(Vec2::ONE);
        assert!(
            (br.o - Vec3::new(2.0, -1.2, 9.5)).length() < 1e-6,
            "{}",
            br.o
        );
        for r in [tl, br] {
            assert!((r.d - Vec3::NEG_Z).length() < 1e-7);
            assert!((r.tmax - 29.5).abs() < 1e-6 && (r.at(r.tmax).z + 20.0).abs() < 1e-5);
        }
    }
}
