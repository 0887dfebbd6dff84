//! The live view of a render in the tev image viewer (`--display-server HOST:PORT`, as
//! pbrt-v4's): the current estimate after a pass, as an image of its own in tev, over tev's
//! network protocol ([`crate::io::tev`]).
//!
//! The render never waits for tev. After a pass the render thread asks [`LiveView::due`]
//! (a lock and a few comparisons); only if a new image is due does it convert its film
//! ([`Frame::from_film`], one pass over the pixels) and hand the frame to
//! [`LiveView::send`], which puts it in a one-place-per-image slot (a newer frame of the
//! same image replaces one not yet sent) and returns. A thread of its own writes the frames
//! to tev. A frame is due when the sender is idle and
//!
//! - at least the minimum interval (`--display-every`, default [`DEFAULT_INTERVAL`]) has
//!   passed since the last one, and at least [`COST_FACTOR`] times what the last frame cost
//!   (its conversion and its sending, wall time): the live view takes at most about
//!   1/[`COST_FACTOR`] = 2% of the render's time, on any image size and link;
//! - and tev is connected, or the next reconnection attempt is due.
//!
//! Nothing about tev is fatal. If tev is not there, or the connection breaks (a failed or
//! timed-out write, or tev closing it), one warning line is printed and the render goes on;
//! the sender tries to connect again every [`RETRY`] (silently), and once more for the last
//! image. A new warning is printed only after a frame has been delivered since the last
//! one. On each connection an image is created (`create image`, channels `R`, `G`, `B` and,
//! with the relative error, `rel_error.R/G/B`) before its first update; every update is the
//! whole image, in blocks of 128² pixels. At the end, [`LiveView::finish`] sends the final
//! state and waits for it to be written, at most [`FINAL_WAIT`].

use crate::film::Film;
use crate::io::tev;
use std::collections::VecDeque;
use std::io::Write;
use std::net::{TcpStream, ToSocketAddrs};
use std::sync::{Arc, Condvar, Mutex, MutexGuard};
use std::thread::JoinHandle;
use std::time::{Duration, Instant};

/// The default minimum interval between two images sent.
pub const DEFAULT_INTERVAL: Duration = Duration::from_millis(500);
/// Frames are at least this many times their own cost apart.
pub const COST_FACTOR: u32 = 50;
/// How often a lost tev is looked for again.
pub const RETRY: Duration = Duration::from_secs(5);
/// How long a connection attempt may take (per address the host name resolves to).
pub const CONNECT_TIMEOUT: Duration = Duration::from_secs(1);
/// How long a write may make no progress before the connection counts as lost.
#[cfg(not(test))]
pub const WRITE_TIMEOUT: Duration = Duration::from_secs(5);
/// The unit tests' (a stalled tev's test waits for it about three times: 15 s of the fast tier
/// with the renderer's 5 s).
#[cfg(test)]
pub const WRITE_TIMEOUT: Duration = Duration::from_millis(500);
/// How long [`LiveView::finish`] waits for the last image to be written.
pub const FINAL_WAIT: Duration = Duration::from_secs(30);
/// Frames of different images waiting at most (a further one drops the oldest).
const MAX_QUEUED: usize = 4;

/// The channels of a frame: R, G, B and, with the relative error, its layer.
pub const RGB: [&str; 3] = ["R", "G", "B"];
pub const REL_ERROR: [&str; 3] = ["rel_error.R", "rel_error.G", "rel_error.B"];

/// The relative standard error of a pixel's estimate, per channel: the standard deviation of
/// the pixel value, √(v / spp) with v the per-sample-equivalent variance
/// ([`Film::sample_variance_f64`], the EXR's `variance` channels) and spp the samples per
/// pixel, over the absolute pixel value; 0 where the pixel value is 0.
pub fn relative_error(mean: f64, variance: f64, spp: f64) -> f64 {
    if mean == 0.0 || spp <= 0.0 {
        0.0
    } else {
        (variance / spp).sqrt() / mean.abs()
    }
}

/// One image to show: its name in tev, size, channels and values (interleaved, row by row).
#[derive(Clone, Debug)]
pub struct Frame {
    pub name: String,
    pub width: usize,
    pub height: usize,
    pub channels: Vec<&'static str>,
    pub data: Vec<f32>,
    /// What building it took (counted in its cost).
    built_in: Duration,
}

impl Frame {
    /// The film's image (the values the EXR holds: each pixel's mean rounded to f32) and,
    /// with `rel_error`, each pixel's [`relative_error`] per channel (computed in f64, then
    /// rounded).
    pub fn from_film(name: &str, film: &Film, rel_error: bool) -> Frame {
        let start = Instant::now();
        let n = if rel_error { 6 } else { 3 };
        let pixels = film.width * film.height;
        let spp = film.spp();
        let mut data = Vec::with_capacity(pixels * n);
        for i in 0..pixels {
            let mean = film.mean_f64(i);
            data.extend(mean.map(|m| m as f32));
            if rel_error {
                let var = film.sample_variance_f64(i, spp);
                data.extend((0..3).map(|c| relative_error(mean[c], var[c], spp) as f32));
            }
        }
        let mut channels = RGB.to_vec();
        if rel_error {
            channels.extend(REL_ERROR);
        }
        Frame {
            name: name.to_string(),
            width: film.width,
            height: film.height,
            channels,
            data,
            built_in: start.elapsed(),
        }
    }
}

/// Checks `HOST:PORT` (a name or address, `[v6]:port` for IPv6) without resolving it.
pub fn parse_address(s: &str) -> Result<String, String> {
    let bad = || {
        format!(
            "'{s}' is not HOST:PORT (e.g. localhost:{}, tev's default)",
            tev::DEFAULT_PORT
        )
    };
    let (host, port) = s.rsplit_once(':').ok_or_else(bad)?;
    let plain = !host.is_empty() && !host.contains(':') && !host.contains(['[', ']']);
    let v6 = host.len() > 2 && host.starts_with('[') && host.ends_with(']');
    match port.parse::<u16>() {
        Ok(p) if p > 0 && (plain || v6) && !host.contains(char::is_whitespace) => Ok(s.to_string()),
        _ => Err(bad()),
    }
}

/// A warning printer (one line each).
pub type Warn = Arc<dyn Fn(&str) + Send + Sync>;

#[derive(Default)]
struct State {
    queue: VecDeque<Frame>,
    /// The sender is writing a frame.
    busy: bool,
    /// [`LiveView::finish`] was called: send what is queued, then stop.
    finishing: bool,
    /// Stop at once (dropped, or the final wait ran out).
    abandoned: bool,
    connected: bool,
    /// No connection attempt before this.
    retry_at: Option<Instant>,
    last_offer: Option<Instant>,
    interval: Duration,
}

struct Shared {
    state: Mutex<State>,
    /// Wakes the sender (a frame, or finishing).
    wake: Condvar,
    /// Wakes [`LiveView::finish`] (a frame written or dropped).
    idle: Condvar,
}

impl Shared {
    fn lock(&self) -> MutexGuard<'_, State> {
        self.state.lock().unwrap_or_else(|e| e.into_inner())
    }
}

/// The live view: a sender thread and the slot frames are handed over in.
pub struct LiveView {
    shared: Arc<Shared>,
    thread: Option<JoinHandle<()>>,
    address: String,
    min_interval: Duration,
    warn: Warn,
}

impl LiveView {
    /// Starts the sender for tev at `address` (checked with [`parse_address`]; it connects
    /// with the first frame). Frames are at least `min_interval` apart.
    pub fn start(address: &str, min_interval: Duration, warn: Warn) -> crate::Result<LiveView> {
        let address = parse_address(address).map_err(crate::Error::Invalid)?;
        let shared = Arc::new(Shared {
            state: Mutex::new(State {
                interval: min_interval,
                ..State::default()
            }),
            wake: Condvar::new(),
            idle: Condvar::new(),
        });
        let thread = {
            let (shared, address, warn) = (shared.clone(), address.clone(), warn.clone());
            std::thread::Builder::new()
                .name("tev".into())
                .spawn(move || Sender::new(address, min_interval, warn).run(&shared))
                .map_err(|e| crate::Error::Invalid(format!("cannot start the live view: {e}")))?
        };
        Ok(LiveView {
            shared,
            thread: Some(thread),
            address,
            min_interval,
            warn,
        })
    }

    /// Whether a new frame would be sent now (see the module doc): cheap, never blocks on
    /// the network.
    pub fn due(&self) -> bool {
        let s = self.shared.lock();
        let now = Instant::now();
        !s.busy
            && s.queue.is_empty()
            && (s.connected || s.retry_at.is_none_or(|t| now >= t))
            && s.last_offer
                .is_none_or(|t| now.duration_since(t) >= s.interval.max(self.min_interval))
    }

    /// Hands a frame to the sender (replacing a frame of the same image not yet sent) and
    /// returns at once.
    pub fn send(&self, frame: Frame) {
        let mut s = self.shared.lock();
        enqueue(&mut s, frame);
        self.shared.wake.notify_all();
    }

    /// Sends `last` (the final state) and waits until every frame handed over is written,
    /// or dropped if tev is not there; at most [`FINAL_WAIT`], then one warning.
    pub fn finish(mut self, last: Option<Frame>) {
        let mut s = self.shared.lock();
        // Finishing before the last frame is seen: it gets its connection attempt.
        s.finishing = true;
        if let Some(f) = last {
            enqueue(&mut s, f);
        }
        self.shared.wake.notify_all();
        let deadline = Instant::now() + FINAL_WAIT;
        while s.busy || !s.queue.is_empty() {
            let now = Instant::now();
            if now >= deadline {
                s.abandoned = true;
                self.shared.wake.notify_all();
                drop(s);
                self.thread = None; // not joined: it may be stuck in a write
                (self.warn)(&format!(
                    "warning: live view: the last image was not written to tev at {} within \
                     {} s; gave up on it",
                    self.address,
                    FINAL_WAIT.as_secs()
                ));
                return;
            }
            s = match self.shared.idle.wait_timeout(s, deadline - now) {
                Ok((g, _)) => g,
                Err(e) => e.into_inner().0,
            };
        }
        drop(s);
        if let Some(t) = self.thread.take() {
            let _ = t.join();
        }
    }
}

/// Queues a frame, replacing a frame of the same image not yet sent.
fn enqueue(s: &mut State, frame: Frame) {
    if let Some(waiting) = s.queue.iter_mut().find(|f| f.name == frame.name) {
        *waiting = frame;
    } else {
        if s.queue.len() >= MAX_QUEUED {
            s.queue.pop_front();
        }
        s.queue.push_back(frame);
    }
    s.last_offer = Some(Instant::now());
}

impl Drop for LiveView {
    /// Without [`LiveView::finish`] (an error ended the render): the sender stops after the
    /// frame under way, not waited for.
    fn drop(&mut self) {
        if self.thread.is_some() {
            self.shared.lock().abandoned = true;
            self.shared.wake.notify_all();
        }
    }
}

/// An open connection to tev and the images created on it.
struct Connection {
    stream: TcpStream,
    created: Vec<(String, usize, usize, Vec<&'static str>)>,
}

/// The sender thread's own state.
struct Sender {
    address: String,
    min_interval: Duration,
    warn: Warn,
    connection: Option<Connection>,
    /// A warning was printed and no frame was delivered since.
    warned: bool,
    /// The connection attempt allowed while finishing was made.
    final_attempt: bool,
    buf: Vec<u8>,
}

impl Sender {
    fn new(address: String, min_interval: Duration, warn: Warn) -> Self {
        Sender {
            address,
            min_interval,
            warn,
            connection: None,
            warned: false,
            final_attempt: false,
            buf: Vec::new(),
        }
    }

    fn run(mut self, shared: &Shared) {
        loop {
            let (frame, finishing, retry_at) = {
                let mut s = shared.lock();
                loop {
                    if s.abandoned {
                        return;
                    }
                    if let Some(f) = s.queue.pop_front() {
                        s.busy = true;
                        break (f, s.finishing, s.retry_at);
                    }
                    if s.finishing {
                        return;
                    }
                    s = match shared.wake.wait(s) {
                        Ok(g) => g,
                        Err(e) => e.into_inner(),
                    };
                }
            };
            let start = Instant::now();
            let mut retry = None;
            let mut delivered = false;
            let mut lost = false;
            if let Some(mut c) = self.connection.take() {
                match self.write_frame(&mut c, &frame) {
                    Ok(()) => {
                        self.connection = Some(c);
                        delivered = true;
                    }
                    Err(e) => {
                        self.warn_lost(&e);
                        lost = true;
                        retry = Some(Instant::now() + RETRY);
                    }
                }
            }
            // Connect: at once after a loss (tev may have been restarted), else when the
            // retry is due, and once for the last image.
            let may_try = !delivered
                && (lost
                    || if finishing {
                        !std::mem::replace(&mut self.final_attempt, true)
                    } else {
                        retry_at.is_none_or(|t| start >= t)
                    });
            if may_try {
                match self.connect() {
                    Ok(mut c) => match self.write_frame(&mut c, &frame) {
                        Ok(()) => {
                            self.connection = Some(c);
                            delivered = true;
                        }
                        Err(e) => {
                            self.warn_lost(&e);
                            retry = Some(Instant::now() + RETRY);
                        }
                    },
                    Err(e) => {
                        self.warn_unreachable(&e);
                        retry = Some(Instant::now() + RETRY);
                    }
                }
            }
            if delivered {
                self.warned = false;
            }
            let cost = delivered.then(|| frame.built_in + start.elapsed());
            let mut s = shared.lock();
            s.busy = false;
            s.connected = self.connection.is_some();
            if retry.is_some() {
                s.retry_at = retry;
            }
            if let Some(cost) = cost {
                s.interval = self.min_interval.max(cost * COST_FACTOR);
            }
            shared.idle.notify_all();
        }
    }

    fn warn_lost(&mut self, e: &std::io::Error) {
        self.warn_once(&format!(
            "warning: live view: lost the connection to tev at {}: {e}; the render goes on \
             (and reconnects every {} s)",
            self.address,
            RETRY.as_secs()
        ));
    }

    fn warn_unreachable(&mut self, e: &std::io::Error) {
        self.warn_once(&format!(
            "warning: live view: cannot reach tev at {}: {e}; the render goes on (and tries \
             again every {} s)",
            self.address,
            RETRY.as_secs()
        ));
    }

    fn warn_once(&mut self, message: &str) {
        if !std::mem::replace(&mut self.warned, true) {
            (self.warn)(message);
        }
    }

    fn connect(&self) -> std::io::Result<Connection> {
        let mut last = None;
        for addr in self.address.to_socket_addrs()? {
            match TcpStream::connect_timeout(&addr, CONNECT_TIMEOUT) {
                Ok(stream) => {
                    stream.set_write_timeout(Some(WRITE_TIMEOUT))?;
                    stream.set_nodelay(true)?;
                    return Ok(Connection {
                        stream,
                        created: Vec::new(),
                    });
                }
                Err(e) => last = Some(e),
            }
        }
        Err(last.unwrap_or_else(|| std::io::Error::other("the host name has no address")))
    }

    /// Writes a frame: the image's creation first if this connection has not made it (at
    /// this size, with these channels), then its blocks.
    fn write_frame(&mut self, c: &mut Connection, f: &Frame) -> std::io::Result<()> {
        check_open(&c.stream)?;
        let protocol = |e: tev::ProtocolError| std::io::Error::other(e.to_string());
        let key = (f.name.clone(), f.width, f.height, f.channels.clone());
        if !c.created.contains(&key) {
            self.buf.clear();
            tev::create_image(&mut self.buf, &f.name, true, f.width, f.height, &f.channels)
                .map_err(protocol)?;
            c.stream.write_all(&self.buf)?;
            c.created.retain(|k| k.0 != f.name);
            c.created.push(key);
        }
        for block in tev::tiles(f.width, f.height) {
            self.buf.clear();
            tev::update_image(
                &mut self.buf,
                &f.name,
                false,
                &f.channels,
                &f.data,
                f.width,
                block,
            )
            .map_err(protocol)?;
            c.stream.write_all(&self.buf)?;
        }
        Ok(())
    }
}

/// tev never writes to its clients: a connection that has something to read is one tev
/// closed (a write into it could still succeed, into the socket's buffer).
fn check_open(stream: &TcpStream) -> std::io::Result<()> {
    stream.set_nonblocking(true)?;
    let r = stream.peek(&mut [0u8; 1]);
    stream.set_nonblocking(false)?;
    match r {
        Ok(0) => Err(std::io::Error::new(
            std::io::ErrorKind::ConnectionAborted,
            "tev closed the connection",
        )),
        Ok(_) => Ok(()),
        Err(e) if e.kind() == std::io::ErrorKind::WouldBlock => Ok(()),
        Err(e) => Err(e),
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::film::{FilmTile, Filter};
    use glam::{Vec2, Vec3};
    use std::net::TcpListener;

    /// A 2 × 1 box-filtered film: pixel 0 got the samples 1 and 3 (per channel scaled by
    /// 1, 2, 4), pixel 1 two samples of 0.
    fn film() -> Film {
        let mut tile = FilmTile::new(0, 0, 2, 1, Filter::Box);
        for v in [1.0, 3.0] {
            tile.add_sample(Vec2::new(0.5, 0.5), Vec3::new(v, 2.0 * v, 4.0 * v));
            tile.add_sample(Vec2::new(1.5, 0.5), Vec3::ZERO);
        }
        let mut film = Film::new(2, 1, Filter::Box);
        film.merge(&tile);
        film
    }

    /// The image and the relative error written out: mean 2 (× 1, 2, 4); the unbiased
    /// variance of the samples 1 and 3 is 2 (× 1, 4, 16) at 2 spp, so the pixel value's
    /// standard deviation is 1 (× 1, 2, 4) and its relative error 1/2 in every channel; the
    /// black pixel's is 0.
    #[test]
    fn a_frame_holds_the_image_and_the_relative_error() {
        let f = Frame::from_film("a", &film(), true);
        assert_eq!(f.channels, [RGB, REL_ERROR].concat());
        assert_eq!(
            f.data,
            [2.0, 4.0, 8.0, 0.5, 0.5, 0.5, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0]
        );
        let f = Frame::from_film("a", &film(), false);
        assert_eq!(f.data, [2.0, 4.0, 8.0, 0.0, 0.0, 0.0]);
    }

    #[test]
    fn addresses_are_host_and_port() {
        for ok in [
            "localhost:14158",
            "127.0.0.1:1",
            "[::1]:14158",
            "tev.example:80",
        ] {
            assert_eq!(parse_address(ok).as_deref(), Ok(ok));
        }
        for bad in [
            "localhost",
            ":14158",
            "localhost:0",
            "host:port",
            "::1:14158",
            "a b:1",
        ] {
            assert!(parse_address(bad).is_err(), "{bad}");
        }
    }

    /// A tev that accepts and never reads: frames handed over return at once however many,
    /// no new frame is due while one is being written, and `finish` ends with one warning
    /// once the write has made no progress for WRITE_TIMEOUT.
    #[test]
    fn a_stalled_tev_never_blocks_the_render() {
        let listener = TcpListener::bind("127.0.0.1:0").unwrap();
        let addr = listener.local_addr().unwrap().to_string();
        let accepted = std::thread::spawn(move || listener.accept().map(|(s, _)| s));
        let warnings = Arc::new(Mutex::new(Vec::<String>::new()));
        let w = warnings.clone();
        let view = LiveView::start(
            &addr,
            Duration::ZERO,
            Arc::new(move |m: &str| w.lock().unwrap().push(m.to_string())),
        )
        .unwrap();
        // 2048² × 3 f32s: 48 MiB, more than the socket buffers of both ends hold.
        let frame = Frame {
            name: "big".into(),
            width: 2048,
            height: 2048,
            channels: RGB.to_vec(),
            data: vec![0.0; 2048 * 2048 * 3],
            built_in: Duration::ZERO,
        };
        assert!(view.due());
        view.send(frame.clone());
        let _conn = accepted.join().unwrap().unwrap();
        // The sender took the frame and is stuck in its write: nothing is due (though
        // nothing waits in the slot), and sending still returns, however often.
        std::thread::sleep(Duration::from_millis(200));
        assert!(!view.due());
        for _ in 0..20 {
            view.send(frame.clone());
        }
        view.finish(None);
        let w = warnings.lock().unwrap();
        assert_eq!(w.len(), 1, "{w:?}");
        assert!(w[0].contains("lost the connection"), "{w:?}");
    }
}
