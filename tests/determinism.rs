//! Reproducibility: each pixel sample draws from its own stream keyed by (seed, pixel,
//! sample), so the film sums are bit-identical at any thread count, and seeds differ.

mod common;
use common::*;

#[test]
fn same_seed_same_bits_with_one_and_two_threads() {
    let scene = load("scenes/cornell-box.xml", &[("res", "40")]);
    let a = render_scene(&scene, 8, 42, Some(1));
    let b = render_scene(&scene, 8, 42, Some(2));
    assert_eq!(a.film.sum, b.film.sum);
    assert_eq!(a.film.sum_sq, b.film.sum_sq);
    assert_eq!(a.film.weight, b.film.weight);
    assert_eq!(a.stats.path, b.stats.path);
}

#[test]
fn different_seeds_give_different_but_statistically_equal_images() {
    let scene = load("scenes/cornell-box.xml", &[("res", "40")]);
    let spp = 32;
    let a = render_scene(&scene, spp, 1, None);
    let b = render_scene(&scene, spp, 2, None);
    assert_ne!(a.film.sum, b.film.sum);
    let (ma, sa) = image_mean_and_se(&a, spp);
    let (mb, sb) = image_mean_and_se(&b, spp);
    for c in 0..3 {
        let z = (ma[c] - mb[c]).abs() / (sa[c] * sa[c] + sb[c] * sb[c]).sqrt();
        assert!(z < 4.5, "channel {c}: z = {z}");
    }
}

#[test]
fn a_continued_render_adds_up_to_the_uninterrupted_one() {
    use penumbra::render::RenderSettings;
    let scene = load("scenes/cornell-box.xml", &[("res", "24")]);
    let run = |spp, first_sample| {
        scene
            .render(
                &RenderSettings {
                    spp,
                    seed: 9,
                    threads: None,
                    sampler: None,
                    first_sample,
                },
                &|_, _| {},
            )
            .unwrap()
            .film
    };
    let whole = run(12, 0);
    let mut parts = run(4, 0);
    parts.add(&run(8, 4));
    // Same samples; only the order of the f64 additions differs.
    for (a, b) in whole.sum.iter().zip(&parts.sum) {
        for c in 0..3 {
            assert!((a[c] - b[c]).abs() <= 1e-12 * a[c].abs().max(1.0));
        }
    }
    assert_eq!(whole.weight, parts.weight);
}

/// The path statistics count what happened: inside a closed diffuse box with unbounded depth
/// every camera path ends by Russian roulette, so `rr_terminated` is the number of paths, and
/// each path makes at least rr_depth bounces.
#[test]
fn path_statistics_count_every_roulette_termination() {
    let scene = scene_from_str(
        r#"<scene version="3.0.0">
        <integrator type="path"><integer name="max_depth" value="-1"/><integer name="rr_depth" value="3"/></integrator>
        <sensor type="perspective"><float name="fov" value="60"/>
            <film type="hdrfilm"><integer name="width" value="8"/><integer name="height" value="6"/></film></sensor>
        <shape type="cube"><transform name="to_world"><scale value="4"/></transform>
            <bsdf type="twosided"><bsdf type="diffuse"><rgb name="reflectance" value="0.5"/></bsdf></bsdf></shape>
    </scene>"#,
    );
    let spp = 16;
    let out = render_scene(&scene, spp, 3, None);
    let paths = 8 * 6 * spp as u64;
    assert_eq!(out.stats.path.rr_terminated, paths, "{:?}", out.stats.path);
    assert!(out.stats.path.bounces >= 3 * paths, "{:?}", out.stats.path);
}
