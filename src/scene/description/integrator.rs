//! Integrators: Mitsuba's `path`, `direct`, `volpath`, `volpathmis` and `ptracer`, and
//! penumbra's `sppm` and `bdpt`, optionally wrapped in `moment`.

use super::*;

#[derive(Clone, Debug, PartialEq)]
pub enum IntegratorDesc {
    /// Mitsuba's `path` integrator. `max_depth` −1 means unbounded.
    Path {
        max_depth: i64,
        rr_depth: i64,
        hide_emitters: bool,
    },
    /// Mitsuba's `volpath` (volumetric path tracing) and `volpathmis` (the same with
    /// spectral and emitter MIS; `use_spectral_mis` only there). `max_depth` −1 means
    /// unbounded.
    VolPath {
        mis: bool,
        max_depth: i64,
        rr_depth: i64,
        hide_emitters: bool,
        use_spectral_mis: bool,
    },
    /// Mitsuba's `ptracer` (particle tracing). `max_depth` −1 means unbounded;
    /// `samples_per_pass` 0 when not given.
    ParticleTracer {
        max_depth: i64,
        rr_depth: i64,
        hide_emitters: bool,
        samples_per_pass: u32,
    },
    /// Bidirectional path tracing (penumbra's own; Mitsuba 3 has none). `max_depth` −1
    /// means unbounded; `strategy` (s, t) renders that connection strategy alone (for
    /// debugging), MIS-weighted or not (`strategy_mis`).
    Bdpt {
        max_depth: i64,
        rr_depth: i64,
        hide_emitters: bool,
        strategy: Option<(u32, u32)>,
        strategy_mis: bool,
        /// `light_paths`: the share of pixel samples that trace a light subpath, in (0, 1];
        /// `None` (left out, or given as 0): chosen by a pilot render.
        light_paths: Option<f64>,
    },
    /// Stochastic progressive photon mapping (penumbra's own; Mitsuba has none).
    /// `photon_count` 0: one photon per pixel per iteration; `initial_radius` 0: automatic.
    Sppm {
        max_depth: i64,
        photon_count: u64,
        initial_radius: f64,
        alpha: f64,
    },
    /// Mitsuba's `direct` integrator: `emitter_samples` and `bsdf_samples` per pixel sample
    /// (each defaulting to `shading_samples`, default 1), combined with the power heuristic.
    Direct {
        emitter_samples: u32,
        bsdf_samples: u32,
        hide_emitters: bool,
    },
    /// Mitsuba's `aov`: `aovs` as (name, type) pairs and nested integrators by name.
    Aov {
        aovs: Vec<(String, AovKind)>,
        nested: Vec<(String, IntegratorDesc)>,
    },
    /// penumbra's `whitted`: recursive ray tracing, direct light from every emitter
    /// (`emitter_samples` per area light), perfect reflection and refraction to `max_depth`.
    Whitted {
        max_depth: u32,
        emitter_samples: u32,
        hide_emitters: bool,
        /// false: direct light without shadow rays (the ladder's "ray casting only").
        shadows: bool,
    },
    /// penumbra's `radiosity`: diffuse patches, Monte Carlo form factors, progressive
    /// refinement.
    Radiosity(RadiosityParams),
}

/// The largest `max_depth` of `whitted` (every glass interface doubles its rays).
pub const WHITTED_MAX_DEPTH: u32 = 20;

/// SPPM's default radius reduction α (Hachisuka and Jensen 2009's 2/3).
pub const SPPM_ALPHA: f64 = 2.0 / 3.0;

/// The AOV types penumbra supports (Mitsuba's names).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum AovKind {
    Depth,
    Position,
    GeoNormal,
    ShNormal,
    Uv,
    Albedo,
}

impl AovKind {
    pub fn from_name(name: &str) -> Option<AovKind> {
        Some(match name {
            "depth" => AovKind::Depth,
            "position" => AovKind::Position,
            "geo_normal" => AovKind::GeoNormal,
            "sh_normal" => AovKind::ShNormal,
            "uv" => AovKind::Uv,
            "albedo" => AovKind::Albedo,
            _ => return None,
        })
    }

    /// The channel suffixes Mitsuba writes for this type.
    pub fn channels(self) -> &'static [&'static str] {
        match self {
            AovKind::Depth => &["T"],
            AovKind::Position | AovKind::GeoNormal | AovKind::ShNormal => &["X", "Y", "Z"],
            AovKind::Uv => &["U", "V"],
            AovKind::Albedo => &["R", "G", "B"],
        }
    }
}

/// How the image is made from the patch solution.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Shading {
    /// Each patch's radiance B/π, constant over the patch.
    Flat,
    /// A final gather: exact emission and direct light at the pixel, indirect light from
    /// the patches one cosine-distributed ray away.
    Gather,
}

impl Shading {
    pub fn from_name(name: &str) -> Option<Self> {
        match name {
            "flat" => Some(Shading::Flat),
            "gather" => Some(Shading::Gather),
            _ => None,
        }
    }
}

/// The radiosity integrator's XML parameters.
#[derive(Clone, Debug, PartialEq)]
pub struct RadiosityParams {
    /// Target number of patches over all surfaces (used when `patch_size` is 0).
    pub patch_count: u32,
    /// Target patch edge length in scene units (0: use `patch_count`).
    pub patch_size: f32,
    /// Form-factor rays from each patch side.
    pub rays_per_patch: u32,
    /// Shooting stops when the unshot power is below this share of the emitted power.
    pub residual: f32,
    pub shading: Shading,
}

impl Default for RadiosityParams {
    fn default() -> Self {
        RadiosityParams {
            patch_count: 1024,
            patch_size: 0.0,
            rays_per_patch: 1024,
            residual: 1e-4,
            shading: Shading::Gather,
        }
    }
}

impl IntegratorDesc {
    /// This integrator replaced by `kind` with its defaults, taking this one's `max_depth`,
    /// `rr_depth` and `hide_emitters` where it has them: `path`, `ptracer` (light tracing),
    /// `bdpt` (bidirectional path tracing),
    /// `sppm` (one photon per pixel per iteration, automatic radius, α = 2/3), `whitted`
    /// (one sample per area light) or `radiosity` (1024 patches, 1024 rays each, final
    /// gather). For rendering a scene written for the path tracer with a light-path
    /// integrator (the validation study's light-tracing entries, `penumbra render
    /// --integrator`).
    pub fn switched_to(&self, kind: &str) -> Result<IntegratorDesc> {
        // (max_depth, rr_depth, hide_emitters); −1: unbounded.
        let (max_depth, rr_depth, hide_emitters) =
            match *self {
                IntegratorDesc::Path {
                    max_depth,
                    rr_depth,
                    hide_emitters,
                }
                | IntegratorDesc::VolPath {
                    max_depth,
                    rr_depth,
                    hide_emitters,
                    ..
                }
                | IntegratorDesc::ParticleTracer {
                    max_depth,
                    rr_depth,
                    hide_emitters,
                    ..
                }
                | IntegratorDesc::Bdpt {
                    max_depth,
                    rr_depth,
                    hide_emitters,
                    ..
                } => (max_depth, rr_depth, hide_emitters),
                IntegratorDesc::Sppm { max_depth, .. } => (max_depth, 5, false),
                IntegratorDesc::Direct { hide_emitters, .. } => (2, 5, hide_emitters),
                IntegratorDesc::Whitted {
                    max_depth,
                    hide_emitters,
                    ..
                } => (max_depth as i64, 5, hide_emitters),
                IntegratorDesc::Radiosity(_) => (8, 5, false),
                IntegratorDesc::Aov { .. } => return Err(Error::Invalid(
                    "an aov scene cannot switch integrator (name one inside the aov integrator)"
                        .into(),
                )),
            };
        Ok(match kind {
            "path" => IntegratorDesc::Path {
                max_depth,
                rr_depth,
                hide_emitters,
            },
            "ptracer" => IntegratorDesc::ParticleTracer {
                max_depth,
                rr_depth,
                hide_emitters,
                samples_per_pass: 0,
            },
            "bdpt" => IntegratorDesc::Bdpt {
                max_depth,
                rr_depth,
                hide_emitters,
                strategy: None,
                strategy_mis: true,
                light_paths: None,
            },
            "sppm" => IntegratorDesc::Sppm {
                max_depth,
                photon_count: 0,
                initial_radius: 0.0,
                alpha: SPPM_ALPHA,
            },
            "whitted" => {
                if !(1..=WHITTED_MAX_DEPTH as i64).contains(&max_depth) {
                    return Err(Error::Invalid(format!(
                        "whitted needs a max_depth in [1, {WHITTED_MAX_DEPTH}]; the scene's integrator has {}",
                        if max_depth < 0 { "-1 (unbounded)".to_string() } else { max_depth.to_string() }
                    )));
                }
                IntegratorDesc::Whitted {
                    max_depth: max_depth as u32,
                    emitter_samples: 1,
                    hide_emitters,
                    shadows: true,
                }
            }
            "radiosity" => IntegratorDesc::Radiosity(RadiosityParams::default()),
            _ => {
                return Err(Error::Invalid(format!(
                "unknown integrator '{kind}' (expected path, ptracer, bdpt, sppm, whitted or radiosity)"
            )))
            }
        })
    }
}

/// The rendering controls of Mitsuba's integrator base classes: `timeout` (seconds, −1:
/// none; returned when set), `block_size` (its image blocks; penumbra's 16x16 tiles do not
/// change the image, so it is only checked) and, for the integrators that render pixel
/// samples (`sampling`), `samples_per_pass` (deprecated in Mitsuba, which splits the render
/// into passes of that many samples: the same image in expectation; penumbra's passes are
/// its own). `hide_emitters` is read by the callers that use it.
fn rendering_controls(o: &Object, p: &mut Props, sampling: bool) -> Result<Option<f64>> {
    let timeout = p.float("timeout", -1.0)?;
    if !timeout.is_finite() || (timeout < 0.0 && timeout != -1.0) {
        return Err(Error::scene(
            &o.location,
            format!(
                "timeout of {} must be >= 0 seconds or -1 (none), got {timeout}",
                describe(o)
            ),
        ));
    }
    if sampling {
        for name in ["block_size", "samples_per_pass"] {
            let v = p.int(name, 0)?;
            if !(0..=u32::MAX as i64).contains(&v) {
                return Err(Error::scene(
                    &o.location,
                    format!("{name} of {} must be >= 0, got {v}", describe(o)),
                ));
            }
        }
    }
    Ok((timeout >= 0.0).then_some(timeout))
}

/// Mitsuba's bounds on `max_depth` (−1: unbounded) and `rr_depth`.
fn check_depths(o: &Object, max_depth: i64, rr_depth: i64) -> Result<()> {
    if max_depth < -1 {
        return Err(Error::scene(
            &o.location,
            format!(
                "max_depth of {} must be -1 (unbounded) or >= 0, got {max_depth}",
                describe(o)
            ),
        ));
    }
    if rr_depth <= 0 {
        return Err(Error::scene(
            &o.location,
            format!("rr_depth of {} must be > 0, got {rr_depth}", describe(o)),
        ));
    }
    Ok(())
}

/// Mitsuba's `aov` integrator: the `aovs` list of `name:type` pairs and nested integrators
/// named by their `name` attribute.
fn aov_desc(o: &Object) -> Result<(IntegratorDesc, Option<f64>)> {
    let mut p = Props::new(o);
    let spec = p
        .string("aovs")?
        .map(|(s, _)| s.to_string())
        .unwrap_or_default();
    let timeout = rendering_controls(o, &mut p, true)?;
    // Read by Mitsuba's base class; the AOVs are geometric and the nested integrators have
    // their own.
    p.boolean("hide_emitters", false)?;
    p.finish()?;
    let mut aovs = Vec::new();
    for item in spec.split(',').map(str::trim).filter(|s| !s.is_empty()) {
        let bad =
            |why: &str| Error::scene(&o.location, format!("{}: AOV '{item}': {why}", describe(o)));
        let (name, kind) = item
            .split_once(':')
            .filter(|(n, k)| !n.is_empty() && !k.is_empty())
            .ok_or_else(|| bad("expected name:type"))?;
        let kind = AovKind::from_name(kind).ok_or_else(|| {
            bad(
                "unsupported type (penumbra supports depth, position, geo_normal, sh_normal, \
                 uv and albedo)",
            )
        })?;
        aovs.push((name.to_string(), kind));
    }
    let mut nested = Vec::new();
    for Child { name, object: c } in &o.children {
        if c.tag != "integrator" {
            return Err(unexpected_child(o, c));
        }
        if matches!(
            c.plugin.as_str(),
            "aov" | "moment" | "ptracer" | "sppm" | "bdpt"
        ) {
            return Err(Error::scene(
                &c.location,
                format!("{} cannot be nested in an aov integrator", describe(c)),
            ));
        }
        let name = name.clone().ok_or_else(|| {
            Error::scene(
                &c.location,
                format!(
                    "{} in an aov integrator needs a name (its channels' prefix)",
                    describe(c)
                ),
            )
        })?;
        nested.push((name, integrator_desc(c)?.0));
    }
    if aovs.is_empty() && nested.is_empty() {
        return Err(Error::scene(
            &o.location,
            format!(
                "{} has no AOVs (give aovs=\"name:type,...\") and no nested integrator",
                describe(o)
            ),
        ));
    }
    Ok((IntegratorDesc::Aov { aovs, nested }, timeout))
}

/// The integrator, whether it was wrapped in Mitsuba's `moment` integrator (which renders
/// its nested integrator and adds the samples' second moment to the output), and its
/// `timeout` in seconds, if any (the outermost one's for a wrapped integrator).
pub(super) fn integrator_desc(o: &Object) -> Result<(IntegratorDesc, bool, Option<f64>)> {
    if o.plugin == "moment" {
        let mut p = Props::new(o);
        let timeout = rendering_controls(o, &mut p, true)?;
        // Read by Mitsuba's base class; the nested integrator has its own.
        p.boolean("hide_emitters", false)?;
        p.finish()?;
        let mut nested = None;
        for Child { object: c, .. } in &o.children {
            if c.tag != "integrator" {
                return Err(unexpected_child(o, c));
            }
            if nested.is_some() {
                return Err(Error::scene(
                    &c.location,
                    format!(
                        "{}: penumbra supports one nested integrator in a moment integrator",
                        describe(c)
                    ),
                ));
            }
            if c.plugin == "moment" {
                return Err(Error::scene(
                    &c.location,
                    "a moment integrator cannot nest another moment integrator",
                ));
            }
            nested = Some(integrator_desc(c)?);
        }
        let (nested, _, nested_timeout) = nested.ok_or_else(|| {
            Error::scene(
                &o.location,
                format!("{} needs a nested <integrator>", describe(o)),
            )
        })?;
        return Ok((nested, true, timeout.or(nested_timeout)));
    }
    if o.plugin == "aov" {
        let (aov, timeout) = aov_desc(o)?;
        return Ok((aov, false, timeout));
    }
    no_children(o)?;
    let mut p = Props::new(o);
    // Mitsuba's sampling integrators (path, volpath, volpathmis, direct and the wrappers)
    // read the sampling controls; its adjoint ptracer reads the timeout only. penumbra's
    // own integrators read none.
    let timeout = match o.plugin.as_str() {
        "path" | "volpath" | "volpathmis" | "direct" => rendering_controls(o, &mut p, true)?,
        "ptracer" => rendering_controls(o, &mut p, false)?,
        _ => None,
    };
    let desc = match o.plugin.as_str() {
        plugin @ ("path" | "volpath" | "volpathmis") => {
            let max_depth = p.int("max_depth", -1)?;
            let rr_depth = p.int("rr_depth", 5)?;
            let hide_emitters = p.boolean("hide_emitters", false)?;
            let use_spectral_mis = if plugin == "volpathmis" {
                p.boolean("use_spectral_mis", true)?
            } else {
                true
            };
            p.finish()?;
            check_depths(o, max_depth, rr_depth)?;
            if plugin == "path" {
                IntegratorDesc::Path {
                    max_depth,
                    rr_depth,
                    hide_emitters,
                }
            } else {
                IntegratorDesc::VolPath {
                    mis: plugin == "volpathmis",
                    max_depth,
                    rr_depth,
                    hide_emitters,
                    use_spectral_mis,
                }
            }
        }
        "ptracer" => {
            let max_depth = p.int("max_depth", -1)?;
            let rr_depth = p.int("rr_depth", 5)?;
            let hide_emitters = p.boolean("hide_emitters", false)?;
            let samples_per_pass = p.int("samples_per_pass", 0)?;
            p.finish()?;
            check_depths(o, max_depth, rr_depth)?;
            if !(0..=u32::MAX as i64).contains(&samples_per_pass) {
                return Err(Error::scene(
                    &o.location,
                    format!(
                        "samples_per_pass of {} must be positive, got {samples_per_pass}",
                        describe(o)
                    ),
                ));
            }
            IntegratorDesc::ParticleTracer {
                max_depth,
                rr_depth,
                hide_emitters,
                samples_per_pass: samples_per_pass as u32,
            }
        }
        "bdpt" => {
            let max_depth = p.int("max_depth", -1)?;
            let rr_depth = p.int("rr_depth", 5)?;
            let hide_emitters = p.boolean("hide_emitters", false)?;
            let strategy_s = p.int("strategy_s", -1)?;
            let strategy_t = p.int("strategy_t", -1)?;
            let strategy_mis = p.boolean("strategy_mis", true)?;
            // 0: chosen by the pilot render.
            let light_paths = Some(p.float("light_paths", 0.0)?).filter(|&x| x != 0.0);
            p.finish()?;
            check_depths(o, max_depth, rr_depth)?;
            let bad = |msg: String| Err(Error::scene(&o.location, msg));
            let strategy = match (strategy_s, strategy_t) {
                (-1, -1) => None,
                (s, t) if s >= 0 && t >= 1 && s + t >= 2 && (s, t) != (1, 1) => {
                    if s > u32::MAX as i64 / 2 || t > u32::MAX as i64 / 2 {
                        return bad(format!("strategy_s/strategy_t of {} are too large", describe(o)));
                    }
                    if max_depth >= 0 && s + t - 1 > max_depth {
                        return bad(format!(
                            "strategy ({s}, {t}) of {} makes paths of {} segments, more than                              max_depth {max_depth}",
                            describe(o),
                            s + t - 1
                        ));
                    }
                    Some((s as u32, t as u32))
                }
                (s, t) => {
                    return bad(format!(
                        "strategy_s and strategy_t of {} must be given together, with                          strategy_s >= 0, strategy_t >= 1, s + t >= 2 and (s, t) not (1, 1);                          got ({s}, {t})",
                        describe(o)
                    ))
                }
            };
            if let Some(x) = light_paths {
                if !(x > 0.0 && x <= 1.0) {
                    return bad(format!(
                        "light_paths of {} is the share of samples that trace a light subpath, \
                         in (0, 1], or 0 for a pilot render's choice; got {x}",
                        describe(o)
                    ));
                }
            }
            if strategy.is_none() && p_has(o, "strategy_mis") {
                return bad(format!(
                    "strategy_mis of {} needs strategy_s and strategy_t",
                    describe(o)
                ));
            }
            IntegratorDesc::Bdpt {
                max_depth,
                rr_depth,
                hide_emitters,
                strategy,
                strategy_mis,
                light_paths,
            }
        }
        "sppm" => {
            let max_depth = p.int("max_depth", -1)?;
            let photon_count = p.int("photon_count", 0)?;
            let initial_radius = p.float("initial_radius", 0.0)?;
            let alpha = p.float("alpha", SPPM_ALPHA)?;
            p.finish()?;
            let bad = |msg: String| Err(Error::scene(&o.location, msg));
            if max_depth < -1 {
                return bad(format!(
                    "max_depth of {} must be -1 (unbounded) or >= 0, got {max_depth}",
                    describe(o)
                ));
            }
            if !(0..=1 << 40).contains(&photon_count) {
                return bad(format!(
                    "photon_count of {} must be in [0, 2^40], got {photon_count}",
                    describe(o)
                ));
            }
            // The render keeps radii as f32: 1e39 would become +inf and no grid could hold it.
            if !(initial_radius >= 0.0 && initial_radius <= f32::MAX as f64) {
                return bad(format!(
                    "initial_radius of {} must be >= 0 and at most 3.4e38 (0: automatic), got {initial_radius}",
                    describe(o)
                ));
            }
            if !(alpha > 0.0 && alpha < 1.0) {
                return bad(format!(
                    "alpha of {} must be in (0, 1), got {alpha}",
                    describe(o)
                ));
            }
            IntegratorDesc::Sppm {
                max_depth,
                photon_count: photon_count as u64,
                initial_radius,
                alpha,
            }
        }
        "direct" => {
            let has = |n: &str| o.properties.iter().any(|q| q.name == n);
            if has("shading_samples") && (has("emitter_samples") || has("bsdf_samples")) {
                return Err(Error::scene(
                    &o.location,
                    "give either 'shading_samples' or 'emitter_samples'/'bsdf_samples', not both",
                ));
            }
            let shading = p.int("shading_samples", 1)?;
            let emitter_samples = p.int("emitter_samples", shading)?;
            let bsdf_samples = p.int("bsdf_samples", shading)?;
            let hide_emitters = p.boolean("hide_emitters", false)?;
            p.finish()?;
            const LIMIT: i64 = 1 << 16;
            for (name, v) in [
                ("shading_samples", shading),
                ("emitter_samples", emitter_samples),
                ("bsdf_samples", bsdf_samples),
            ] {
                if !(0..=LIMIT).contains(&v) {
                    return Err(Error::scene(
                        &o.location,
                        format!("{name} of {} must be in [0, {LIMIT}], got {v}", describe(o)),
                    ));
                }
            }
            if emitter_samples + bsdf_samples == 0 {
                return Err(Error::scene(
                    &o.location,
                    format!("{} needs at least 1 BSDF or emitter sample", describe(o)),
                ));
            }
            IntegratorDesc::Direct {
                emitter_samples: emitter_samples as u32,
                bsdf_samples: bsdf_samples as u32,
                hide_emitters,
            }
        }
        "whitted" => {
            const MAX_DEPTH: u32 = WHITTED_MAX_DEPTH;
            let max_depth = p.int("max_depth", 6)?;
            let emitter_samples = p.int("emitter_samples", 1)?;
            let hide_emitters = p.boolean("hide_emitters", false)?;
            let shadows = p.boolean("shadows", true)?;
            p.finish()?;
            if !(1..=MAX_DEPTH as i64).contains(&max_depth) {
                return Err(Error::scene(
                    &o.location,
                    format!(
                        "max_depth of {} must be in [1, {MAX_DEPTH}] (every glass interface \
                         doubles its rays), got {max_depth}",
                        describe(o)
                    ),
                ));
            }
            if !(1..=1 << 16).contains(&emitter_samples) {
                return Err(Error::scene(
                    &o.location,
                    format!(
                        "emitter_samples of {} must be in [1, 65536], got {emitter_samples}",
                        describe(o)
                    ),
                ));
            }
            IntegratorDesc::Whitted {
                max_depth: max_depth as u32,
                emitter_samples: emitter_samples as u32,
                hide_emitters,
                shadows,
            }
        }
        "radiosity" => {
            let d = RadiosityParams::default();
            let patch_count = p.int("patch_count", d.patch_count as i64)?;
            let patch_size = p.float("patch_size", 0.0)?;
            let rays_per_patch = p.int("rays_per_patch", d.rays_per_patch as i64)?;
            let residual = p.float("residual", d.residual as f64)?;
            let shading = p.string("shading")?;
            p.finish()?;
            let bad = |msg: String| Err(Error::scene(&o.location, msg));
            let shading = match shading {
                None => d.shading,
                Some((name, loc)) => match Shading::from_name(name) {
                    Some(s) => s,
                    None => {
                        return Err(Error::scene(
                            loc,
                            format!(
                                "shading of {} must be 'flat' or 'gather', got '{name}'",
                                describe(o)
                            ),
                        ))
                    }
                },
            };
            if !(1..=1 << 22).contains(&patch_count) {
                return bad(format!(
                    "patch_count of {} must be in [1, 4194304], got {patch_count}",
                    describe(o)
                ));
            }
            if !(patch_size >= 0.0 && patch_size.is_finite()) {
                return bad(format!(
                    "patch_size of {} must be >= 0 (0: use patch_count), got {patch_size}",
                    describe(o)
                ));
            }
            if !(1..=1 << 20).contains(&rays_per_patch) {
                return bad(format!(
                    "rays_per_patch of {} must be in [1, 1048576], got {rays_per_patch}",
                    describe(o)
                ));
            }
            // Every patch has two sides that may become patches of the solution, each
            // casting rays_per_patch rays; meshing gives at least patch_count patches, so
            // the layout's own check (the radiosity_rays limit) would refuse this product
            // too, after loading the whole scene.
            let rays = 2 * patch_count as u64 * rays_per_patch as u64;
            let limits = crate::limits::current()?;
            let limit = crate::limits::Limit::RadiosityRays;
            if patch_size == 0.0 && rays > limits.radiosity_rays {
                return bad(format!(
                    "patch_count ({patch_count}) x 2 sides x rays_per_patch ({rays_per_patch}) \
                     of {} is {rays} form-factor rays, more than {} (lower patch_count or \
                     rays_per_patch, or raise it with {})",
                    describe(o),
                    limit.of(limits.radiosity_rays),
                    limit.setting()
                ));
            }
            if !(residual > 0.0 && residual < 1.0) {
                return bad(format!(
                    "residual of {} must be in (0, 1), got {residual}",
                    describe(o)
                ));
            }
            IntegratorDesc::Radiosity(RadiosityParams {
                patch_count: patch_count as u32,
                patch_size: patch_size as f32,
                rays_per_patch: rays_per_patch as u32,
                residual: residual as f32,
                shading,
            })
        }
        _ => return Err(unsupported_plugin(o)),
    };
    Ok((desc, false, timeout))
}

/// Whether `o` gives the property `name`.
fn p_has(o: &Object, name: &str) -> bool {
    o.properties.iter().any(|q| q.name == name)
}
