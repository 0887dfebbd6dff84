//! Ray casting in batches: every ray of a batch traced through the scene's hierarchy
//! ([`crate::accel::Accel`], the traversal the integrators use), timed. This is the
//! measurement of issue 42's "rays per second against Mitsuba's own ray casting on the same
//! rays" (`validation/perf/rays.py` gives Mitsuba's `ray_intersect_preliminary` and
//! `ray_test`, i.e. Embree, the same batch), and a check that both renderers see the same
//! geometry: the distances must agree ray by ray.
//!
//! A closest-hit query gives the distance of the nearest hit with 0 < t < tmax (infinity on
//! a miss), as Mitsuba's preliminary intersection does (no surface interaction is
//! computed); an occlusion query gives 1 where anything lies on the ray, else 0.

use crate::error::{Error, Result};
use crate::geometry::Ray;
use crate::scene::Scene;
use rayon::prelude::*;
use std::time::Instant;

/// What a batch asks of each ray.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Query {
    /// The distance to the nearest hit (infinity on a miss).
    Closest,
    /// 1 if anything lies on the ray, else 0.
    Any,
}

/// Rays per parallel work item: large enough that scheduling is lost in the traversal.
const CHUNK: usize = 4096;

/// Traces `rays` (world space, as the scene file places things) through `scene` with `threads` workers (default: one per core); returns
/// one value per ray (see [`Query`]) and the seconds the traversal took (the pool is started
/// before the clock).
pub fn cast(
    scene: &Scene,
    rays: &[Ray],
    query: Query,
    threads: Option<usize>,
) -> Result<(Vec<f32>, f64)> {
    if let Some(bad) = rays
        .iter()
        .position(|r| !(r.o.is_finite() && r.d.is_finite() && r.d.length_squared() > 0.0))
    {
        return Err(Error::Invalid(format!(
            "ray {bad}: origin and direction must be finite and the direction non-zero"
        )));
    }
    // The scene is built camera-relative (`Scene::world_origin`): the rays' origins move
    // with it, subtracted in f64 and rounded once.
    let shift = scene.world_origin.as_dvec3();
    let rays: Vec<Ray> = rays
        .iter()
        .map(|r| Ray::new((r.o.as_dvec3() - shift).as_vec3(), r.d, r.tmax))
        .collect();
    let pool = crate::render::thread_pool(threads)?;
    let mut out = vec![0.0f32; rays.len()];
    let start = Instant::now();
    pool.install(|| {
        out.par_chunks_mut(CHUNK)
            .zip(rays.par_chunks(CHUNK))
            .for_each(|(out, rays)| {
                for (v, ray) in out.iter_mut().zip(rays) {
                    *v = match query {
                        Query::Closest => scene
                            .accel
                            .intersect(ray, &scene.shapes)
                            .map_or(f32::INFINITY, |h| h.t),
                        Query::Any => scene.accel.occluded(ray, &scene.shapes) as u32 as f32,
                    };
                }
            })
    });
    Ok((out, start.elapsed().as_secs_f64()))
}

#[cfg(test)]
mod tests {
    use super::*;
    use glam::Vec3;

    fn scene() -> Scene {
        // A unit sphere at the origin and a 2x2 rectangle in the plane z = -3, seen from a
        // camera away from the origin (the scene is built relative to it).
        let xml = r#"<scene version="3.0.0">
            <sensor type="perspective"><transform name="to_world"><lookat origin="3, 4, 12" target="0, 0, 0" up="0, 1, 0"/></transform><film type="hdrfilm"><integer name="width" value="4"/><integer name="height" value="4"/></film></sensor>
            <shape type="sphere"><point name="center" x="0" y="0" z="0"/><float name="radius" value="1"/></shape>
            <shape type="rectangle"><transform name="to_world"><translate z="-3"/></transform></shape>
        </scene>"#;
        crate::render::Job::from_xml_str(xml, std::path::Path::new("inline.xml"), &[])
            .expect("the test scene loads")
            .scene
    }

    #[test]
    fn distances_and_occlusion_are_the_geometrys() {
        let s = scene();
        let z = Vec3::new(0.0, 0.0, -1.0);
        let rays = [
            // through the sphere's centre from z = 5: hits at t = 4
            Ray::new(Vec3::new(0.0, 0.0, 5.0), z, f32::INFINITY),
            // beside the sphere, onto the rectangle: t = 3.5 + 3 = 6.5
            Ray::new(Vec3::new(0.9, 0.95, 3.5), z, f32::INFINITY),
            // beside both
            Ray::new(Vec3::new(1.5, 1.5, 5.0), z, f32::INFINITY),
            // through the sphere, but stopped short of it
            Ray::new(Vec3::new(0.0, 0.0, 5.0), z, 3.5),
        ];
        for threads in [1, 2] {
            let (t, _) = cast(&s, &rays, Query::Closest, Some(threads)).unwrap();
            assert!((t[0] - 4.0).abs() < 1e-5, "{t:?}");
            assert!((t[1] - 6.5).abs() < 1e-5, "{t:?}");
            assert_eq!(t[2], f32::INFINITY);
            assert_eq!(t[3], f32::INFINITY);
            let (hit, _) = cast(&s, &rays, Query::Any, Some(threads)).unwrap();
            assert_eq!(hit, [1.0, 1.0, 0.0, 0.0]);
        }
    }

    #[test]
    fn a_ray_without_a_direction_is_refused() {
        let s = scene();
        let bad = [Ray::new(Vec3::ZERO, Vec3::ZERO, 1.0)];
        let e = cast(&s, &bad, Query::Closest, None).unwrap_err();
        assert!(e.to_string().contains("ray 0"), "{e}");
        let nan = [Ray::new(Vec3::ZERO, Vec3::new(f32::NAN, 0.0, 1.0), 1.0)];
        assert!(cast(&s, &nan, Query::Any, None).is_err());
    }
}
