//! Reconstruction filters (normalisation, constant images, the splatted variance) and the
//! thin-lens camera (centre and corner rays, aperture 0 = pinhole, sharp focal plane).

mod common;
use common::*;
use glam::{DMat4, DVec3, Vec2, Vec3};
use penumbra::camera::{PerspectiveCamera, ThinLens};
use penumbra::film::{Film, FilmTile, Filter};
use penumbra::sampler::SampleStream;
use penumbra::study::stats::erfc;

const FILTERS: [Filter; 5] = [
    Filter::Box,
    Filter::Tent { radius: 1.0 },
    Filter::Tent { radius: 1.7 },
    Filter::Gaussian { stddev: 0.5 },
    Filter::Gaussian { stddev: 0.3 },
];

/// ∫ w over the support, in closed form.
fn analytic_integral(f: Filter) -> f64 {
    match f {
        Filter::Box => 1.0,
        Filter::Tent { radius } => radius,
        Filter::Gaussian { stddev } => {
            // ∫_{-r}^{r} exp(−x²/2σ²) dx − 2r exp(−r²/2σ²), r = 4σ
            let r = 4.0 * stddev;
            stddev * (2.0 * std::f64::consts::PI).sqrt() * (1.0 - erfc(4.0 / 2f64.sqrt()))
                - 2.0 * r * (-8.0f64).exp()
        }
    }
}

#[test]
fn each_filter_integrates_to_one_over_its_support() {
    for f in FILTERS {
        let r = f.radius();
        let norm = analytic_integral(f);
        // Midpoint rule on the separable 2D filter over its square support.
        let n = 2000;
        let h = 2.0 * r / n as f64;
        let w1: Vec<f64> = (0..n)
            .map(|i| f.weight(-r + (i as f64 + 0.5) * h) / norm)
            .collect();
        let one_d: f64 = w1.iter().sum::<f64>() * h;
        let two_d: f64 = w1
            .iter()
            .map(|a| w1.iter().map(|b| a * b).sum::<f64>())
            .sum::<f64>()
            * h
            * h;
        assert!((one_d - 1.0).abs() < 1e-5, "{f:?}: 1D integral {one_d}");
        assert!((two_d - 1.0).abs() < 2e-5, "{f:?}: 2D integral {two_d}");
        // The film's own quadrature agrees.
        let m = f.weight_moment(0.0, -10.0, 10.0, 1) / norm;
        assert!((m - 1.0).abs() < 1e-9, "{f:?}: weight_moment {m}");
        assert_eq!(f.weight(r), 0.0);
        assert!(f.weight(r * 0.999) >= 0.0);
    }
    // Mitsuba's gaussian: shifted to reach 0 at 2 px, peak 1 − e⁻⁸.
    let g = Filter::DEFAULT;
    assert_eq!(g.radius(), 2.0);
    assert!((g.weight(0.0) - (1.0 - (-8.0f64).exp())).abs() < 1e-15);
    assert!((g.weight(1.0) - ((-2.0f64).exp() - (-8.0f64).exp())).abs() < 1e-15);
}

fn constant_scene(filter: &str, w: usize, h: usize) -> String {
    format!(
        r#"<scene version="3.0.0">
    <integrator type="path"><integer name="max_depth" value="1"/></integrator>
    <sensor type="perspective">
        <float name="fov" value="60"/>
        <film type="hdrfilm">
            <integer name="width" value="{w}"/>
            <integer name="height" value="{h}"/>
            {filter}
        </film>
    </sensor>
    <emitter type="constant"><rgb name="radiance" value="0.7, 0.5, 0.3"/></emitter>
</scene>"#
    )
}

#[test]
fn a_constant_image_stays_constant_under_every_filter_including_the_border() {
    // 37x23: partial tiles, and every pixel at most 2 px from a tile edge or the border.
    for filter in [
        r#"<rfilter type="box"/>"#,
        r#"<rfilter type="tent"/>"#,
        r#"<rfilter type="tent"><float name="radius" value="1.7"/></rfilter>"#,
        "", // Mitsuba's default gaussian
        r#"<rfilter type="gaussian"><float name="stddev" value="0.3"/></rfilter>"#,
    ] {
        let scene = scene_from_str(&constant_scene(filter, 37, 23));
        let out = render_scene(&scene, 3, 1, Some(2));
        let expected = [0.7f32, 0.5, 0.3];
        for (i, p) in out.film.image().iter().enumerate() {
            for c in 0..3 {
                assert!(
                    (p[c] - expected[c]).abs() <= 1e-6 * expected[c],
                    "{filter}: pixel ({}, {}) channel {c} = {}",
                    i % 37,
                    i / 37,
                    p[c]
                );
            }
        }
        assert!(out
            .film
            .sample_variance()
            .iter()
            .all(|v| v.iter().all(|&x| x < 1e-10)));
        assert_eq!(out.film.samples, 37 * 23 * 3);
    }
}

#[test]
fn variance_factor_matches_mitsubas_filter() {
    // K = ∫w² / (∫w)² per axis, computed by validation/mitsuba/render_reference.py from
    // Mitsuba 3.9.1's own rfilter.eval (llvm_ad_rgb) for images 8 (gaussian) and 4 (tent)
    // pixels wide. Mitsuba's float32 gaussian differs from exp(−x²/2σ²) − e⁻⁸ by up to
    // 4e-4 relative near the peak and 2e-2 in the far tail (measured), hence 1e-4 here.
    let gauss = [0.73490459, 0.56625838, 0.5649254, 0.5649254];
    for (i, k) in gauss.iter().enumerate() {
        let ours = Filter::DEFAULT.variance_factor_1d(i, 8);
        assert!(
            (ours - k).abs() < 1e-4 * k,
            "gaussian pixel {i}: {ours} vs {k}"
        );
        assert!((Filter::DEFAULT.variance_factor_1d(7 - i, 8) - ours).abs() < 1e-12);
    }
    let tent = Filter::Tent { radius: 1.0 };
    // Exact: 40/49 at the border (half the tent clipped), 2/3 inside.
    for (i, k) in [40.0 / 49.0, 2.0 / 3.0].iter().enumerate() {
        let ours = tent.variance_factor_1d(i, 4);
        assert!((ours - k).abs() < 1e-9, "tent pixel {i}: {ours} vs {k}");
    }
    assert_eq!(Filter::Box.variance_factor_1d(0, 4), 1.0);
}

#[test]
fn splatted_variance_is_spp_times_the_variance_of_the_pixel_value() {
    // Samples of per-sample variance 1 (uniform on [0, √12)), spp 16, on a 12x12 film,
    // rendered as one tile, 300 times with independent streams. For every filter, the
    // film's variance channel / spp must predict the variance of the pixel values across
    // the repetitions, and match σ² Kx Ky (with K the filter's variance factor).
    let (w, h, spp, reps) = (12usize, 12usize, 16u64, 300u64);
    let s12 = 12f32.sqrt();
    for f in [Filter::Box, Filter::Tent { radius: 1.0 }, Filter::DEFAULT] {
        let mut sum = vec![0.0f64; w * h];
        let mut sum_sq = vec![0.0f64; w * h];
        let mut predicted = vec![0.0f64; w * h];
        for rep in 0..reps {
            let mut tile = FilmTile::new(0, 0, w, h, f);
            for px in 0..w * h {
                for s in 0..spp {
                    let mut rng = SampleStream::new(rep, px as u64, s);
                    let pos = Vec2::new((px % w) as f32, (px / w) as f32) + rng.next_2d();
                    tile.add_sample(pos, Vec3::splat(rng.next_1d() * s12));
                }
            }
            let mut film = Film::new(w, h, f);
            film.merge(&tile);
            let img = film.image();
            let var = film.sample_variance();
            for i in 0..w * h {
                sum[i] += img[i][0] as f64;
                sum_sq[i] += (img[i][0] as f64).powi(2);
                predicted[i] += var[i][0] as f64 / spp as f64 / reps as f64;
            }
        }
        let (mut ratio_film, mut ratio_k) = (0.0, 0.0);
        for i in 0..w * h {
            let m = sum[i] / reps as f64;
            let emp = (sum_sq[i] / reps as f64 - m * m) * reps as f64 / (reps - 1) as f64;
            let k = f.variance_factor_1d(i % w, w) * f.variance_factor_1d(i / w, h);
            ratio_film += emp / predicted[i] / (w * h) as f64;
            ratio_k += emp / (k / spp as f64) / (w * h) as f64;
        }
        // Each pixel's empirical variance has a relative sd of √(2/299) ≈ 0.082; averaged
        // over 144 pixels (positively correlated through shared samples) well below 0.02.
        // (Without Bessel's correction the box filter's ratio would be 16/15 = 1.067.)
        eprintln!("{f:?}: empirical / film {ratio_film:.4}, empirical / K {ratio_k:.4}");
        assert!((ratio_film - 1.0).abs() < 0.04, "{f:?}: film {ratio_film}");
        assert!((ratio_k - 1.0).abs() < 0.04, "{f:?}: K {ratio_k}");
    }
}

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

fn distance_to_line(p: Vec3, o: Vec3, d: Vec3) -> f32 {
    let v = p - o;
    (v - d.normalize() * v.dot(d.normalize())).length()
}

#[test]
fn thin_lens_rays_through_centre_and_corners_meet_on_the_plane_of_focus() {
    let m = look(
        DVec3::new(0.0, 1.0, 6.0),
        DVec3::new(0.0, 1.0, 0.0),
        DVec3::Y,
    );
    let pinhole = PerspectiveCamera::new(m, 50.0, 1.5, 0.01, 1000.0);
    let fd = 4.0;
    let lens = pinhole.clone().with_thin_lens(ThinLens {
        aperture_radius: 0.3,
        focus_distance: fd,
    });
    assert!(lens.needs_aperture_sample() && !pinhole.needs_aperture_sample());
    for s in [
        Vec2::splat(0.5),
        Vec2::ZERO,
        Vec2::new(1.0, 0.0),
        Vec2::new(0.0, 1.0),
        Vec2::ONE,
    ] {
        let p = pinhole.generate_ray(s);
        // Where the pinhole ray crosses the plane of focus, at depth fd along −z.
        let o_cam = Vec3::new(0.0, 1.0, 6.0);
        let t = (fd as f32 - (o_cam.z - p.o.z)) / -p.d.z;
        let focus_point = p.o + p.d * t;
        for k in 0..64 {
            let u = SampleStream::new(5, k, 0).next_2d();
            let r = lens.generate_ray_lens(s, u);
            assert!(distance_to_line(focus_point, r.o, r.d) < 2e-5, "{s} {u}");
            // The origin lies on the near plane, within the aperture around the axis.
            let start = r.o - r.d * (0.01 / -r.d.z);
            assert!((start.z - 6.0).abs() < 1e-5);
            assert!((Vec3::new(start.x, start.y - 1.0, 0.0)).length() <= 0.3 + 1e-5);
        }
    }
    // The centre ray through the middle of the lens is the optical axis.
    let r = lens.generate_ray_lens(Vec2::splat(0.5), Vec2::splat(0.5));
    assert!((r.d - Vec3::new(0.0, 0.0, -1.0)).length() < 1e-6);
}

#[test]
fn thin_lens_with_aperture_zero_is_the_pinhole() {
    let m = look(
        DVec3::new(1.0, 2.0, 3.0),
        DVec3::new(-1.0, 0.5, 0.0),
        DVec3::Y,
    );
    let pinhole = PerspectiveCamera::new(m, 40.0, 0.75, 0.1, 100.0);
    let lens = pinhole.clone().with_thin_lens(ThinLens {
        aperture_radius: 0.0,
        focus_distance: 2.5,
    });
    for i in 0..=10 {
        for j in 0..=10 {
            let s = Vec2::new(i as f32 / 10.0, j as f32 / 10.0);
            let a = pinhole.generate_ray(s);
            let b = lens.generate_ray_lens(s, Vec2::new(0.37, 0.81));
            assert!((a.o - b.o).length() < 1e-6, "{s}: {} vs {}", a.o, b.o);
            assert!((a.d - b.d).length() < 1e-6, "{s}: {} vs {}", a.d, b.d);
            assert!((a.tmax - b.tmax).abs() < 1e-4 * a.tmax);
        }
    }
}

/// A 64x64 thin-lens view of a tiny sphere light at depth `depth` on the ray through the
/// centre of pixel (40, 20); the lens is focused at 5.
fn tiny_light_image(depth: f64) -> Vec<[f32; 3]> {
    let cam = PerspectiveCamera::new(
        look(DVec3::ZERO, DVec3::new(0.0, 0.0, -1.0), DVec3::Y),
        30.0,
        1.0,
        0.01,
        100.0,
    );
    let d = cam
        .generate_ray(Vec2::new(40.5 / 64.0, 20.5 / 64.0))
        .d
        .as_dvec3();
    let c = d / -d.z * depth;
    let xml = format!(
        r#"<scene version="3.0.0">
    <integrator type="path"><integer name="max_depth" value="1"/></integrator>
    <sensor type="thinlens">
        <float name="fov" value="30"/>
        <float name="aperture_radius" value="0.4"/>
        <float name="focus_distance" value="5"/>
        <transform name="to_world"><lookat origin="0, 0, 0" target="0, 0, -1" up="0, 1, 0"/></transform>
        <film type="hdrfilm">
            <integer name="width" value="64"/><integer name="height" value="64"/>
            <rfilter type="box"/>
        </film>
    </sensor>
    <shape type="sphere">
        <point name="center" x="{}" y="{}" z="{}"/>
        <float name="radius" value="0.008"/>
        <emitter type="area"><float name="radiance" value="1"/></emitter>
    </shape>
</scene>"#,
        c.x, c.y, c.z
    );
    render_scene(&scene_from_str(&xml), 256, 3, None)
        .film
        .image()
}

#[test]
fn points_on_the_focal_plane_project_sharply() {
    // Pixel footprint at depth 5: 2·5·tan 15° / 64 ≈ 0.042; the sphere's image (radius
    // 0.008) lies inside pixel (40, 20), whatever lens sample a ray went through.
    let img = tiny_light_image(5.0);
    let lit: Vec<usize> = (0..img.len()).filter(|&i| img[i][0] > 0.0).collect();
    assert_eq!(
        lit,
        vec![20 * 64 + 40],
        "in focus: only the sphere's pixel is lit"
    );
    // Away from the focal plane the same light is spread over its circle of confusion:
    // at depth 10 its diameter is 2·0.4·(10 − 5)/10 = 0.4 at the light, ≈ 4.7 pixels.
    let img = tiny_light_image(10.0);
    let lit = img.iter().filter(|p| p[0] > 0.0).count();
    assert!(lit >= 12, "out of focus: {lit} pixels lit");
}
