//! Checkpoints: a render's running sums on disk (the `PNBRCKP5` format, and `PNBRCKP4` read),
//! written atomically with retries, read whole or header first, checked before a resume; and
//! the scene identity ([`scene_hash`]) they store.

use super::{Progress, ProgressiveSettings};
use crate::error::{Error, Result};
use crate::film::{ExactFilm, Film, Filter, EXACT_VALUES};
use crate::render::RenderStats;
use crate::scene::Scene;
use std::io::Read;
use std::path::Path;
use std::time::Duration;

/// Waits before the second, third, ... attempt of a checkpoint write.
pub const CHECKPOINT_RETRY_DELAYS: [Duration; 2] =
    [Duration::from_millis(100), Duration::from_millis(400)];

/// Writes a checkpoint (or part file), trying again after each of
/// [`CHECKPOINT_RETRY_DELAYS`] when a write fails (a full disk that is cleared, a file
/// system that hiccups); the last failure is returned with the number of attempts.
pub fn write_checkpoint_retrying(c: &Checkpoint, path: &Path) -> Result<()> {
    let mut attempt = 0;
    loop {
        match c.write(path) {
            Ok(()) => return Ok(()),
            Err(e) => match CHECKPOINT_RETRY_DELAYS.get(attempt) {
                Some(delay) => std::thread::sleep(*delay),
                None => {
                    return Err(Error::Invalid(format!(
                        "{e} ({} attempts)",
                        CHECKPOINT_RETRY_DELAYS.len() + 1
                    )))
                }
            },
        }
        attempt += 1;
    }
}

/// FNV-1a, 64 bit: a stable hash for scene identity (not for security).
pub fn fnv1a(bytes: &[u8], mut h: u64) -> u64 {
    for b in bytes {
        h ^= *b as u64;
        h = h.wrapping_mul(0x100_0000_01b3);
    }
    h
}

/// Identity of a scene for checkpoints: its typed description (every parameter, after
/// defaults and -D overrides) and the bytes of every file it loads (meshes, grids, images),
/// each read up to the largest file any loader reads under the limits in effect
/// ([`crate::limits::Limits::input_file_bytes`]; the defaults' if `PENUMBRA_LIMITS` is
/// malformed, which the loaders refuse).
pub fn scene_hash(desc: &crate::scene::description::SceneDescription) -> u64 {
    let bound = crate::limits::current()
        .unwrap_or_default()
        .input_file_bytes();
    let mut h = fnv1a(format!("{desc:?}").as_bytes(), 0xcbf2_9ce4_8422_2325);
    for path in desc.files() {
        // Streamed, and bounded as the loaders are: a device, a FIFO, a directory or a file
        // larger than any loader reads is left out here (its loader then refuses it).
        let mut file_h = h;
        let read = crate::io::read_file_chunks(path, bound, |chunk| file_h = fnv1a(chunk, file_h));
        if read.is_ok() {
            h = file_h;
        }
    }
    h
}

/// A render's running sums on disk.
#[derive(Clone, Debug)]
pub struct Checkpoint {
    pub version: String,
    pub scene_hash: u64,
    pub seed: u64,
    pub pass_spp: u32,
    /// The sampler's points per pass ([`crate::sampler::Sampler::sample_count`]): a resumed
    /// render continues with the same passes.
    pub sampler_points: u32,
    /// The samples per pixel this file holds: [first_sample, first_sample + samples).
    pub first_sample: u64,
    pub samples: u64,
    /// The render's target spp (a part's plan; a checkpoint's `--spp`).
    pub plan_spp: u64,
    /// Where the part's plan starts (`--start-spp`; 0 for a checkpoint).
    pub plan_start: u64,
    /// For a part file: (i, N) of `--part i/N`; None for a checkpoint.
    pub part: Option<(u32, u32)>,
    pub stats: RenderStats,
    pub filter: Filter,
    pub exact: ExactFilm,
    /// An SPPM render's state (its `exact` film is then empty).
    pub sppm: Option<crate::integrator::sppm::SppmState>,
}

/// What a checkpoint or part file says about itself, without its sums: enough to plan a
/// merge before any film is read.
#[derive(Clone, Debug)]
pub struct CheckpointHeader {
    pub version: String,
    pub scene_hash: u64,
    pub seed: u64,
    pub pass_spp: u32,
    pub sampler_points: u32,
    pub first_sample: u64,
    pub samples: u64,
    pub plan_spp: u64,
    pub plan_start: u64,
    pub part: Option<(u32, u32)>,
    pub stats: RenderStats,
    pub filter: Filter,
    pub width: usize,
    pub height: usize,
    /// The film's sample count.
    pub film_samples: u64,
}

impl PartialEq for CheckpointHeader {
    fn eq(&self, o: &Self) -> bool {
        let stats = |s: &RenderStats| {
            (
                s.paths,
                s.path.rays,
                s.path.bounces,
                s.path.rr_terminated,
                s.nonfinite,
                s.seconds.to_bits(),
            )
        };
        self.version == o.version
            && (
                self.scene_hash,
                self.seed,
                self.pass_spp,
                self.sampler_points,
            ) == (o.scene_hash, o.seed, o.pass_spp, o.sampler_points)
            && (
                self.first_sample,
                self.samples,
                self.plan_spp,
                self.plan_start,
            ) == (o.first_sample, o.samples, o.plan_spp, o.plan_start)
            && self.part == o.part
            && stats(&self.stats) == stats(&o.stats)
            && self.filter == o.filter
            && (self.width, self.height, self.film_samples) == (o.width, o.height, o.film_samples)
    }
}

/// Today's format: the header, then the exact film's canonical state
/// ([`ExactFilm::write_state`]: 270 B per pixel plus spilled values), then the SPPM section.
const MAGIC: &[u8; 8] = b"PNBRCKP5";
/// The format before exact-at-any-scale films (issue 40): the same header, then every sum as
/// an i128 count of 2⁻⁴⁸ (240 B per pixel). Read (converted exactly: a count q is q · 2⁻⁴⁸),
/// never written.
const MAGIC_V4: &[u8; 8] = b"PNBRCKP4";

/// An SPPM pixel in a checkpoint: L_d (3), N, τ (3), radius, as f64.
const SPPM_PIXEL_BYTES: usize = 64;

/// The longest version string a checkpoint may hold (a longer one is corrupt).
const MAX_VERSION_BYTES: usize = 256;

/// Header bytes after the magic, besides the version string: u32 version length, 9 u64, 5
/// u32, an f64, 5 u64 and an f64.
const HEADER_FIXED_BYTES: usize = 4 + 9 * 8 + 5 * 4 + 8 + 5 * 8 + 8;

/// Where a file's bytes are: for its error messages.
fn corrupt(path: &Path, m: &str) -> Error {
    Error::Invalid(format!(
        "{}: not a valid penumbra checkpoint or part file ({m})",
        path.display()
    ))
}

/// Parses the header after the magic; returns it and the position after it.
fn parse_header(bytes: &[u8], path: &Path) -> Result<(CheckpointHeader, usize)> {
    let bad = |m: &str| corrupt(path, m);
    let mut r = Reader { b: bytes, pos: 8 };
    let vlen = r.u32().ok_or_else(|| bad("truncated"))? as usize;
    if vlen > MAX_VERSION_BYTES {
        return Err(bad("bad version"));
    }
    let version = String::from_utf8(r.take(vlen).ok_or_else(|| bad("truncated"))?.to_vec())
        .map_err(|_| bad("bad version"))?;
    let mut u = || r.u64().ok_or_else(|| bad("truncated"));
    let (scene_hash, seed, first_sample, samples, plan_spp) = (u()?, u()?, u()?, u()?, u()?);
    let plan_start = u()?;
    let (width, height, film_samples) = (u()?, u()?, u()?);
    let pixels = width.checked_mul(height).ok_or_else(|| bad("resolution"))?;
    let limits = crate::limits::current()?;
    if pixels > limits.render_pixels {
        return Err(Error::Invalid(format!(
            "{}: the checkpoint or part file's resolution of {width}x{height} pixels exceeds {}",
            path.display(),
            limits.exceeded(crate::limits::Limit::RenderPixels)
        )));
    }
    let mut u = || r.u32().ok_or_else(|| bad("truncated"));
    let (pass_spp, sampler_points, part_i, part_n, filter_kind) = (u()?, u()?, u()?, u()?, u()?);
    let filter_param = r.f64().ok_or_else(|| bad("truncated"))?;
    let filter = match filter_kind {
        0 => Filter::Box,
        1 => Filter::Tent {
            radius: filter_param,
        },
        2 => Filter::Gaussian {
            stddev: filter_param,
        },
        _ => return Err(bad("unknown filter")),
    };
    let mut u = || r.u64().ok_or_else(|| bad("truncated"));
    let (paths, rays, bounces, rr, nonfinite) = (u()?, u()?, u()?, u()?, u()?);
    let seconds = r.f64().ok_or_else(|| bad("truncated"))?;
    if pass_spp == 0 || sampler_points == 0 {
        return Err(bad("zero pass size"));
    }
    if first_sample.checked_add(samples).is_none() || plan_start > plan_spp {
        return Err(bad("sample range"));
    }
    let part = (part_n > 0).then_some((part_i, part_n));
    if part.is_some_and(|(i, n)| i >= n) {
        return Err(bad("part index out of range"));
    }
    let header = CheckpointHeader {
        version,
        scene_hash,
        seed,
        pass_spp,
        sampler_points,
        first_sample,
        samples,
        plan_spp,
        plan_start,
        part,
        stats: RenderStats {
            paths,
            path: crate::integrator::PathStats {
                rays,
                bounces,
                rr_terminated: rr,
            },
            nonfinite,
            seconds,
            ..Default::default()
        },
        filter,
        width: width as usize,
        height: height as usize,
        film_samples,
    };
    Ok((header, r.pos))
}

impl Checkpoint {
    pub(super) fn from_progress(
        p: &Progress,
        s: &ProgressiveSettings,
        pass_spp: u32,
        scene: &Scene,
    ) -> Self {
        Checkpoint {
            version: crate::VERSION.to_string(),
            scene_hash: s.scene_hash,
            seed: s.seed,
            pass_spp,
            sampler_points: scene.sampler.sample_count,
            first_sample: 0,
            samples: p.samples,
            plan_spp: s.spp as u64,
            plan_start: 0,
            part: None,
            stats: p.stats,
            filter: scene.filter,
            exact: p.exact.clone(),
            sppm: p.sppm.clone(),
        }
    }

    /// Everything but the sums.
    pub fn header(&self) -> CheckpointHeader {
        CheckpointHeader {
            version: self.version.clone(),
            scene_hash: self.scene_hash,
            seed: self.seed,
            pass_spp: self.pass_spp,
            sampler_points: self.sampler_points,
            first_sample: self.first_sample,
            samples: self.samples,
            plan_spp: self.plan_spp,
            plan_start: self.plan_start,
            part: self.part,
            stats: self.stats,
            filter: self.filter,
            width: self.exact.width,
            height: self.exact.height,
            film_samples: self.exact.samples,
        }
    }

    pub(super) fn check_matches(
        &self,
        scene: &Scene,
        s: &ProgressiveSettings,
        pass_spp: u32,
    ) -> Result<()> {
        let refuse = |what: String| {
            Err(Error::Invalid(format!(
                "cannot resume: the checkpoint was made {what}"
            )))
        };
        if self.part.is_some() || self.first_sample != 0 {
            return refuse("by `render --part`: merge parts with `penumbra merge`".into());
        }
        if self.version != crate::VERSION {
            return refuse(format!(
                "by penumbra {} (this is {})",
                self.version,
                crate::VERSION
            ));
        }
        if self.scene_hash != s.scene_hash {
            return refuse("from another scene (or other -D values, mesh files or --mode)".into());
        }
        if self.seed != s.seed {
            return refuse(format!(
                "with seed {} (this render uses {})",
                self.seed, s.seed
            ));
        }
        if (self.exact.width, self.exact.height) != (scene.width, scene.height)
            || self.pass_spp != pass_spp
            || self.filter != scene.filter
        {
            return refuse("for another resolution".into());
        }
        if self.sampler_points != scene.sampler.sample_count {
            return refuse(format!(
                "with {} sampler points per pass (this render uses {})",
                self.sampler_points, scene.sampler.sample_count
            ));
        }
        Ok(())
    }

    /// The file's bytes (see [`Checkpoint::write`]): a function of the header and the exact
    /// sums alone, so that two groupings of the same passes give the same bytes.
    pub fn to_bytes(&self) -> Vec<u8> {
        let mut buf = Vec::with_capacity(
            256 + self.exact.width * self.exact.height * (18 * EXACT_VALUES + SPPM_PIXEL_BYTES),
        );
        buf.extend_from_slice(MAGIC);
        let v = self.version.as_bytes();
        buf.extend_from_slice(&(v.len() as u32).to_le_bytes());
        buf.extend_from_slice(v);
        let (part_i, part_n) = self.part.unwrap_or((0, 0));
        let (filter_kind, filter_param) = match self.filter {
            Filter::Box => (0u32, 0.0f64),
            Filter::Tent { radius } => (1, radius),
            Filter::Gaussian { stddev } => (2, stddev),
        };
        for x in [
            self.scene_hash,
            self.seed,
            self.first_sample,
            self.samples,
            self.plan_spp,
            self.plan_start,
            self.exact.width as u64,
            self.exact.height as u64,
            self.exact.samples,
        ] {
            buf.extend_from_slice(&x.to_le_bytes());
        }
        for x in [
            self.pass_spp,
            self.sampler_points,
            part_i,
            part_n,
            filter_kind,
        ] {
            buf.extend_from_slice(&x.to_le_bytes());
        }
        buf.extend_from_slice(&filter_param.to_le_bytes());
        let st = &self.stats;
        for x in [
            st.paths,
            st.path.rays,
            st.path.bounces,
            st.path.rr_terminated,
            st.nonfinite,
        ] {
            buf.extend_from_slice(&x.to_le_bytes());
        }
        buf.extend_from_slice(&st.seconds.to_le_bytes());
        self.exact.write_state(&mut buf);
        match &self.sppm {
            None => buf.push(0),
            Some(st) => {
                buf.push(1);
                buf.extend_from_slice(&st.iterations.to_le_bytes());
                buf.extend_from_slice(&st.photons_emitted.to_le_bytes());
                for i in 0..st.ld.len() {
                    let (ld, tau) = (st.ld[i], st.tau[i]);
                    for v in [
                        ld.x,
                        ld.y,
                        ld.z,
                        st.big_n[i],
                        tau.x,
                        tau.y,
                        tau.z,
                        st.radius[i],
                    ] {
                        buf.extend_from_slice(&v.to_le_bytes());
                    }
                }
            }
        }
        let checksum = fnv1a(&buf, 0xcbf2_9ce4_8422_2325);
        buf.extend_from_slice(&checksum.to_le_bytes());
        buf
    }

    /// Writes atomically ([`crate::io::atomic`]): to a temporary file of a unique name next
    /// to `path`, synced, then renamed over it, so that a crash never leaves a half-written
    /// checkpoint and two processes writing the same path never mix their bytes.
    pub fn write(&self, path: &Path) -> Result<()> {
        crate::io::atomic::write_bytes(path, &self.to_bytes()).map_err(|cause| Error::Io {
            path: path.to_path_buf(),
            cause,
        })
    }

    /// Reads a checkpoint or part file written by [`Checkpoint::write`] (or by the previous
    /// format, `PNBRCKP4`, converted exactly).
    pub fn read(path: &Path) -> Result<Self> {
        let bytes =
            crate::io::read_file_limited(path, checkpoint_file_limit()?).map_err(|cause| {
                Error::Io {
                    path: path.to_path_buf(),
                    cause,
                }
            })?;
        Self::parse(&bytes, path)
    }

    /// Reads only a file's header (a bounded prefix of it), checking that the file is as long
    /// as its resolution needs: for planning a merge before reading any film. The rest, and
    /// the checksum, are checked when the whole file is read.
    pub fn read_header(path: &Path) -> Result<CheckpointHeader> {
        let io = |cause| Error::Io {
            path: path.to_path_buf(),
            cause,
        };
        let (f, len) = crate::io::open_regular(path, checkpoint_file_limit()?).map_err(io)?;
        let mut prefix = Vec::new();
        f.take((8 + HEADER_FIXED_BYTES + MAX_VERSION_BYTES) as u64)
            .read_to_end(&mut prefix)
            .map_err(io)?;
        let (magic, h, pos) = Self::parse_magic_and_header(&prefix, path)?;
        let film =
            (h.width * h.height) as u64 * if magic == 4 { 16 } else { 18 } * EXACT_VALUES as u64;
        if len < pos as u64 + film + 1 + 8 {
            return Err(corrupt(path, "size does not match the resolution"));
        }
        Ok(h)
    }

    fn parse_magic_and_header(bytes: &[u8], path: &Path) -> Result<(u8, CheckpointHeader, usize)> {
        let bad = |m: &str| corrupt(path, m);
        let magic = match bytes.get(..8) {
            Some(m) if m == MAGIC => 5,
            Some(m) if m == MAGIC_V4 => 4,
            Some(m) if &m[..7] == b"PNBRCKP" => return Err(bad("written by an older penumbra")),
            _ => return Err(bad("wrong magic")),
        };
        let (h, pos) = parse_header(bytes, path)?;
        Ok((magic, h, pos))
    }

    /// Parses the bytes of a checkpoint or part file; `path` names it in errors. Never
    /// panics, and allocates only for a film whose bytes are all present.
    pub fn parse(bytes: &[u8], path: &Path) -> Result<Self> {
        let bad = |m: &str| corrupt(path, m);
        if bytes.len() < 16 {
            return Err(bad("wrong magic"));
        }
        match &bytes[..8] {
            m if m == MAGIC || m == MAGIC_V4 => {}
            m if &m[..7] == b"PNBRCKP" => return Err(bad("written by an older penumbra")),
            _ => return Err(bad("wrong magic")),
        }
        // The checksum first: a corrupt file says so, whatever field the damage hit.
        let (body, tail) = bytes.split_at(bytes.len() - 8);
        if fnv1a(body, 0xcbf2_9ce4_8422_2325).to_le_bytes() != tail {
            return Err(bad("checksum mismatch"));
        }
        let (magic, h, pos) = Self::parse_magic_and_header(bytes, path)?;
        if pos > body.len() {
            return Err(bad("truncated"));
        }
        let pixels = h.width * h.height;
        let (exact, film_end) = if magic == 4 {
            // PNBRCKP4: i128 counts of 2^-48, converted exactly.
            let film_bytes = pixels * EXACT_VALUES * 16;
            let counts = body
                .get(pos..pos + film_bytes)
                .ok_or_else(|| bad("size does not match the resolution"))?;
            let mut exact = ExactFilm::new(h.width, h.height);
            exact.samples = h.film_samples;
            for (j, q) in counts.chunks_exact(16).enumerate() {
                let q = i128::from_le_bytes(q.try_into().map_err(|_| bad("truncated"))?);
                exact.add_parts(j / EXACT_VALUES, j % EXACT_VALUES, q, -48);
            }
            (exact, pos + film_bytes)
        } else {
            let (exact, used) =
                ExactFilm::read_state(&body[pos..], h.width, h.height, h.film_samples)
                    .map_err(|e| bad(&e.to_string()))?;
            (exact, pos + used)
        };
        let left = body.len() - film_end;
        if left != 1 && left != 1 + 16 + pixels * SPPM_PIXEL_BYTES {
            return Err(bad("size does not match the resolution"));
        }
        let mut r = Reader {
            b: body,
            pos: film_end,
        };
        let sppm = match r.take(1).ok_or_else(|| bad("truncated"))?[0] {
            0 if left == 1 => None,
            1 if left > 1 => {
                let mut u = || r.u64().ok_or_else(|| bad("truncated"));
                let (iterations, photons_emitted) = (u()?, u()?);
                let mut st = crate::integrator::sppm::SppmState {
                    iterations,
                    photons_emitted,
                    ld: Vec::with_capacity(pixels),
                    big_n: Vec::with_capacity(pixels),
                    tau: Vec::with_capacity(pixels),
                    radius: Vec::with_capacity(pixels),
                };
                for _ in 0..pixels {
                    let mut v = [0.0f64; 8];
                    for x in v.iter_mut() {
                        *x = r.f64().ok_or_else(|| bad("truncated"))?;
                    }
                    if !v.iter().all(|x| x.is_finite()) || v[3] < 0.0 || v[7] < 0.0 {
                        return Err(bad("sppm state"));
                    }
                    st.ld.push(glam::DVec3::new(v[0], v[1], v[2]));
                    st.big_n.push(v[3]);
                    st.tau.push(glam::DVec3::new(v[4], v[5], v[6]));
                    st.radius.push(v[7]);
                }
                Some(st)
            }
            _ => return Err(bad("unknown section")),
        };
        Ok(Checkpoint {
            version: h.version,
            scene_hash: h.scene_hash,
            seed: h.seed,
            pass_spp: h.pass_spp,
            sampler_points: h.sampler_points,
            first_sample: h.first_sample,
            samples: h.samples,
            plan_spp: h.plan_spp,
            plan_start: h.plan_start,
            part: h.part,
            stats: h.stats,
            filter: h.filter,
            exact,
            sppm,
        })
    }

    /// The f64 film of the sums.
    pub fn film(&self) -> Film {
        self.exact.to_film(self.filter)
    }
}

struct Reader<'a> {
    b: &'a [u8],
    pos: usize,
}

impl Reader<'_> {
    fn take(&mut self, n: usize) -> Option<&[u8]> {
        let s = self.b.get(self.pos..self.pos.checked_add(n)?)?;
        self.pos += n;
        Some(s)
    }
    fn u32(&mut self) -> Option<u32> {
        Some(u32::from_le_bytes(self.take(4)?.try_into().ok()?))
    }
    fn u64(&mut self) -> Option<u64> {
        Some(u64::from_le_bytes(self.take(8)?.try_into().ok()?))
    }
    fn f64(&mut self) -> Option<f64> {
        Some(f64::from_le_bytes(self.take(8)?.try_into().ok()?))
    }
}

/// The largest checkpoint or part file read: its film at the `render_pixels` limit, 18 bytes
/// per value, plus room for spilled values (an exact sum over f64's whole range takes at
/// most 2,100 bits, 272 bytes with its key): a bound before allocating, and special files
/// (a checkpoint path at /dev/zero, a FIFO) are refused by [`crate::io::open_regular`].
fn checkpoint_file_limit() -> Result<u64> {
    let pixels = crate::limits::current()?.render_pixels;
    Ok(pixels
        .saturating_mul(EXACT_VALUES as u64)
        .saturating_mul(18 + 272)
        .saturating_add(1 << 20))
}
