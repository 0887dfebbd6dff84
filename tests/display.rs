//! The live view (`penumbra render --display-server HOST:PORT`, `converge --display-server`)
//! against a stand-in for tev: a TCP listener on the loopback interface that decodes every
//! packet with `io::tev` (whose bytes equal tev's own client's: `tests/tev_protocol.rs`).
//! What tev would show: the image created at the render's size with its channels, each
//! update covering the whole image once, the last one equal to the EXR written; and a tev
//! that is not there, or goes away in the middle, costs one warning line and nothing else.

use penumbra::io::exr::{self, RgbImage};
use penumbra::io::tev::{self, Packet};
use std::net::TcpListener;
use std::path::{Path, PathBuf};
use std::process::{Command, Output};
use std::thread::JoinHandle;

const CORNELL: &str = include_str!(concat!(
    env!("CARGO_MANIFEST_DIR"),
    "/scenes/cornell-box.xml"
));

/// Not square and wider than two of tev's 128-pixel blocks, taller than one: six blocks,
/// the last in each row and column partial; a swapped width and height shows.
const W: usize = 150;
const H: usize = 140;

/// A temporary directory unique to this process and test, removed on drop.
struct TempDir(PathBuf);

impl TempDir {
    fn new(test: &str) -> Self {
        let dir =
            std::env::temp_dir().join(format!("penumbra-display-{}-{test}", std::process::id()));
        let _ = std::fs::remove_dir_all(&dir);
        std::fs::create_dir_all(&dir).unwrap();
        TempDir(dir)
    }

    fn path(&self, name: &str) -> PathBuf {
        self.0.join(name)
    }
}

impl Drop for TempDir {
    fn drop(&mut self) {
        let _ = std::fs::remove_dir_all(&self.0);
    }
}

/// The Cornell box at W × H, written as `box.xml` (its live image is "box seed S").
fn scene(dir: &TempDir) -> PathBuf {
    let mut text = CORNELL.to_string();
    for (axis, v) in [("width", W), ("height", H)] {
        let from = format!(r#"<integer name="{axis}" value="$res"/>"#);
        assert_eq!(text.matches(&from).count(), 1, "{from}");
        text = text.replace(&from, &format!(r#"<integer name="{axis}" value="{v}"/>"#));
    }
    let path = dir.path("box.xml");
    std::fs::write(&path, text).unwrap();
    path
}

fn penumbra(args: &[&str]) -> Output {
    Command::new(env!("CARGO_BIN_EXE_penumbra"))
        .args(args)
        .output()
        .expect("run penumbra")
}

fn warnings(out: &Output) -> Vec<String> {
    String::from_utf8_lossy(&out.stderr)
        .lines()
        .filter(|l| l.contains("warning"))
        .map(str::to_string)
        .collect()
}

fn assert_success(out: &Output) {
    assert!(
        out.status.success(),
        "status {:?}, stderr:\n{}",
        out.status,
        String::from_utf8_lossy(&out.stderr)
    );
}

/// The packets of one connection, to its end.
fn read_all(mut stream: std::net::TcpStream) -> Vec<Packet> {
    let mut packets = Vec::new();
    while let Some(bytes) = tev::read_packet(&mut stream, 1 << 26).expect("a whole packet") {
        packets.push(tev::decode(&bytes).expect("a well-formed packet"));
    }
    packets
}

/// Reads one connection's packets up to and including the first whole-image update (its
/// blocks cover W × H), then closes it.
fn read_first_frame(mut stream: std::net::TcpStream) -> Vec<Packet> {
    let mut packets = Vec::new();
    let mut covered = 0;
    while covered < W * H {
        let bytes = tev::read_packet(&mut stream, 1 << 26)
            .expect("a whole packet")
            .expect("the first image before the connection ends");
        let p = tev::decode(&bytes).unwrap();
        if let Packet::Update { width, height, .. } = &p {
            covered += (*width * *height) as usize;
        }
        packets.push(p);
    }
    packets
}

/// A packet in a line (without its values).
fn describe(p: &Packet) -> String {
    match p {
        Packet::Update {
            name,
            x,
            y,
            width,
            height,
            ..
        } => format!("update of {name:?} at {x},{y} {width}x{height}"),
        other => format!("{other:?}"),
    }
}

/// A port nothing listens on (bound, then released).
fn dead_port() -> String {
    let l = TcpListener::bind("127.0.0.1:0").unwrap();
    l.local_addr().unwrap().to_string()
}

/// Splits a connection's packets into what tev would hold: the created image (name, size,
/// channels) and the frames, each the image's values (interleaved) after one whole-image
/// update, checking that every update's blocks cover the image exactly once and name the
/// created image and its channels.
struct Seen {
    name: String,
    width: usize,
    height: usize,
    channels: Vec<String>,
    frames: Vec<Vec<f32>>,
}

fn frames(packets: &[Packet]) -> Seen {
    let Some(Packet::Create {
        name,
        width,
        height,
        channels,
        ..
    }) = packets.first()
    else {
        panic!(
            "the first packet does not create an image: {}",
            packets.first().map_or("none".into(), describe)
        );
    };
    let (w, h, n) = (*width as usize, *height as usize, channels.len());
    let mut frames = Vec::new();
    let mut image = vec![f32::NAN; w * h * n];
    let mut count = vec![0u32; w * h];
    for p in &packets[1..] {
        let Packet::Update {
            name: image_name,
            channels: update_channels,
            x,
            y,
            width: bw,
            height: bh,
            ..
        } = p
        else {
            panic!("not an update after the creation: {}", describe(p));
        };
        assert_eq!(image_name, name);
        assert_eq!(update_channels, channels);
        let (x, y, bw, bh) = (*x as usize, *y as usize, *bw as usize, *bh as usize);
        assert!(
            x + bw <= w && y + bh <= h,
            "block {x},{y} {bw}x{bh} outside {w}x{h}"
        );
        for (c, _) in channels.iter().enumerate() {
            let values = p
                .channel_values(c)
                .expect("offsets and strides within the data");
            for j in 0..bh {
                for i in 0..bw {
                    image[((y + j) * w + x + i) * n + c] = values[j * bw + i];
                }
            }
        }
        for j in y..y + bh {
            for i in x..x + bw {
                count[j * w + i] += 1;
            }
        }
        if count.iter().all(|&k| k >= 1) {
            assert!(
                count.iter().all(|&k| k == 1),
                "an update covers some pixels twice"
            );
            frames.push(image.clone());
            count.fill(0);
        }
    }
    assert!(
        count.iter().all(|&k| k == 0),
        "the last update covers only part of the image"
    );
    Seen {
        name: name.clone(),
        width: w,
        height: h,
        channels: channels.clone(),
        frames,
    }
}

/// The frame equals the EXR: R, G, B bit for bit (both are the film's means rounded to
/// f32), and each rel_error channel equal, to float precision, to √(variance / spp) / |value|
/// from the EXR's variance channels and spp (relative 1e-6: two f32 roundings of the
/// inputs, one of the result).
fn assert_frame_is_exr(frame: &[f32], channels: usize, out: &Path) {
    let image: RgbImage = exr::read(out).unwrap();
    let spp = image.spp().unwrap();
    for (i, rgb) in image.rgb.iter().enumerate() {
        let px = &frame[i * channels..(i + 1) * channels];
        for c in 0..3 {
            assert_eq!(
                px[c].to_bits(),
                rgb[c].to_bits(),
                "pixel {i} channel {c}: live {} EXR {}",
                px[c],
                rgb[c]
            );
        }
        if channels == 6 {
            let var = image.variance.as_ref().expect("variance channels")[i];
            for c in 0..3 {
                let v = rgb[c] as f64;
                let want = if v == 0.0 {
                    0.0
                } else {
                    (var[c] as f64 / spp).sqrt() / v.abs()
                };
                let got = px[3 + c] as f64;
                assert!(
                    (got - want).abs() <= 1e-6 * want,
                    "pixel {i} channel {c}: rel_error {got}, from the EXR {want}"
                );
            }
        }
    }
}

/// A render with --variance: one image "box seed 3" of W × H with channels R, G, B and the
/// rel_error layer; with --display-every 1h exactly two images: the first pass's (nothing
/// was sent before) and the final one, which differ (six passes of 12 spp) and the last of
/// which is the EXR.
#[test]
fn tev_sees_the_image_created_updated_whole_and_ending_on_the_exr() {
    let dir = TempDir::new("render");
    let scene = scene(&dir);
    let out = dir.path("out.exr");
    let listener = TcpListener::bind("127.0.0.1:0").unwrap();
    let addr = listener.local_addr().unwrap().to_string();
    let tev: JoinHandle<Vec<Packet>> =
        std::thread::spawn(move || read_all(listener.accept().unwrap().0));
    let run = penumbra(&[
        "render",
        scene.to_str().unwrap(),
        "--spp",
        "72",
        "--seed",
        "3",
        "--variance",
        "--display-server",
        &addr,
        "--display-every",
        "1h",
        "-o",
        out.to_str().unwrap(),
    ]);
    assert_success(&run);
    assert_eq!(warnings(&run), Vec::<String>::new());
    let seen = frames(&tev.join().unwrap());
    assert_eq!(seen.name, "box seed 3");
    assert_eq!((seen.width, seen.height), (W, H));
    assert_eq!(
        seen.channels,
        ["R", "G", "B", "rel_error.R", "rel_error.G", "rel_error.B"]
    );
    assert_eq!(seen.frames.len(), 2);
    assert_ne!(seen.frames[0], seen.frames[1]);
    assert_frame_is_exr(&seen.frames[1], 6, &out);
}

/// Nothing listening: one warning line naming the address, and the same image, bit for bit,
/// as the render without a live view.
#[test]
fn no_tev_is_one_warning_and_the_same_image() {
    let dir = TempDir::new("dead");
    let scene = scene(&dir);
    let (with, without) = (dir.path("with.exr"), dir.path("without.exr"));
    let addr = dead_port();
    let common = [
        scene.to_str().unwrap(),
        "--spp",
        "36",
        "--display-every",
        "0",
    ];
    let run = penumbra(
        &[
            &["render"][..],
            &common[..],
            &["--display-server", &addr, "-o", with.to_str().unwrap()],
        ]
        .concat(),
    );
    assert_success(&run);
    let w = warnings(&run);
    assert_eq!(w.len(), 1, "{w:?}");
    assert!(
        w[0].contains(&format!("cannot reach tev at {addr}")),
        "{w:?}"
    );
    let plain = penumbra(&[
        "render",
        common[0],
        "--spp",
        "36",
        "-o",
        without.to_str().unwrap(),
    ]);
    assert_success(&plain);
    assert_eq!(
        exr::read(&with).unwrap().rgb,
        exr::read(&without).unwrap().rgb
    );
}

/// tev goes away after the first image (its connection closed, and no one listening any
/// more): one warning line, the render ends normally.
#[test]
fn tev_gone_mid_render_is_one_warning() {
    let dir = TempDir::new("gone");
    let scene = scene(&dir);
    let out = dir.path("out.exr");
    let listener = TcpListener::bind("127.0.0.1:0").unwrap();
    let addr = listener.local_addr().unwrap().to_string();
    let tev = std::thread::spawn(move || {
        let first = read_first_frame(listener.accept().unwrap().0);
        drop(listener);
        first
    });
    let run = penumbra(&[
        "render",
        scene.to_str().unwrap(),
        "--spp",
        "72",
        "--display-server",
        &addr,
        "--display-every",
        "0",
        "-o",
        out.to_str().unwrap(),
    ]);
    assert_success(&run);
    let w = warnings(&run);
    assert_eq!(w.len(), 1, "{w:?}");
    assert!(w[0].contains("lost the connection"), "{w:?}");
    assert_eq!(frames(&tev.join().unwrap()).frames.len(), 1);
    assert!(exr::read(&out).is_ok());
}

/// tev restarted mid-render (the first connection closed, a new one accepted): one warning,
/// and the new connection gets the image created again and, last, the EXR's values.
#[test]
fn the_live_view_reconnects_to_a_restarted_tev() {
    let dir = TempDir::new("restart");
    let scene = scene(&dir);
    let out = dir.path("out.exr");
    let listener = TcpListener::bind("127.0.0.1:0").unwrap();
    let addr = listener.local_addr().unwrap().to_string();
    let tev = std::thread::spawn(move || {
        let first = read_first_frame(listener.accept().unwrap().0);
        let second = read_all(listener.accept().unwrap().0);
        (first, second)
    });
    let run = penumbra(&[
        "render",
        scene.to_str().unwrap(),
        "--spp",
        "72",
        "--display-server",
        &addr,
        "--display-every",
        "0",
        "-o",
        out.to_str().unwrap(),
    ]);
    assert_success(&run);
    let w = warnings(&run);
    assert_eq!(w.len(), 1, "{w:?}");
    let (first, second) = tev.join().unwrap();
    assert_eq!(frames(&first).frames.len(), 1);
    let seen = frames(&second);
    assert_eq!(seen.channels, ["R", "G", "B"]);
    assert_frame_is_exr(seen.frames.last().expect("a frame"), 3, &out);
}

/// `converge --display-server`: one image per ladder (scene, sweep value, seed), each
/// updated after its rungs.
#[test]
fn converge_shows_each_ladder_as_an_image() {
    let dir = TempDir::new("converge");
    let scene = scene(&dir);
    let reference = dir.path("ref.exr");
    assert_success(&penumbra(&[
        "render",
        scene.to_str().unwrap(),
        "--spp",
        "8",
        "-o",
        reference.to_str().unwrap(),
    ]));
    let listener = TcpListener::bind("127.0.0.1:0").unwrap();
    let addr = listener.local_addr().unwrap().to_string();
    let tev = std::thread::spawn(move || read_all(listener.accept().unwrap().0));
    let run = penumbra(&[
        "converge",
        scene.to_str().unwrap(),
        "--reference",
        reference.to_str().unwrap(),
        "--spp",
        "1,2,4",
        "--seeds",
        "2",
        "--sweep",
        "max_depth=2,3",
        "--out-dir",
        dir.path("conv").to_str().unwrap(),
        "--display-server",
        &addr,
        "-q",
    ]);
    assert_success(&run);
    let packets = tev.join().unwrap();
    let mut created: Vec<String> = packets
        .iter()
        .filter_map(|p| match p {
            Packet::Create {
                name,
                width,
                height,
                ..
            } => {
                assert_eq!((*width as usize, *height as usize), (W, H));
                Some(name.clone())
            }
            _ => None,
        })
        .collect();
    created.sort();
    assert_eq!(
        created,
        [
            "box max_depth=2 seed 0",
            "box max_depth=2 seed 1",
            "box max_depth=3 seed 0",
            "box max_depth=3 seed 1"
        ]
    );
}
