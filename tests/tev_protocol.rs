//! penumbra's tev protocol (`io::tev`) against tev's own Python client: the bytes penumbra
//! writes for open, create, a whole-image update and close equal, byte for byte, those
//! `tevclient` 1.0.4 sent for the same four commands, recorded by `tests/data/tev/record.py`
//! into `tests/data/tev/tevclient-stream.bin.gz` (the commands and the image's values are
//! written out in both).

use penumbra::io::tev::{self, Packet};
use std::io::Read;

const WIDTH: usize = 130;
const HEIGHT: usize = 129;
const NAME: &str = "cornell-box seed 7";
const CHANNELS: [&str; 6] = ["R", "G", "B", "rel_error.R", "rel_error.G", "rel_error.B"];
const OPEN_PATH: &str = "renders/cornell-box.exr";

/// v(x, y, c) = ((31 x + 17 y + 7 c) mod 97) / 7 − 3 in f64, rounded to f32 (as numpy does
/// in the script), interleaved.
fn image() -> Vec<f32> {
    let mut v = Vec::with_capacity(WIDTH * HEIGHT * CHANNELS.len());
    for y in 0..HEIGHT {
        for x in 0..WIDTH {
            for c in 0..CHANNELS.len() {
                v.push((((31 * x + 17 * y + 7 * c) % 97) as f64 / 7.0 - 3.0) as f32);
            }
        }
    }
    v
}

fn recorded() -> Vec<u8> {
    let path = concat!(
        env!("CARGO_MANIFEST_DIR"),
        "/tests/data/tev/tevclient-stream.bin.gz"
    );
    let file = std::fs::File::open(path).expect("the recorded stream");
    let mut bytes = Vec::new();
    flate2::read::GzDecoder::new(file)
        .read_to_end(&mut bytes)
        .expect("a gzip stream");
    bytes
}

fn penumbra_stream() -> Vec<u8> {
    let image = image();
    let mut out = Vec::new();
    tev::open_image(&mut out, OPEN_PATH, "", true).unwrap();
    tev::create_image(&mut out, NAME, true, WIDTH, HEIGHT, &CHANNELS).unwrap();
    for block in tev::tiles(WIDTH, HEIGHT) {
        tev::update_image(&mut out, NAME, false, &CHANNELS, &image, WIDTH, block).unwrap();
    }
    tev::close_image(&mut out, NAME).unwrap();
    out
}

#[test]
fn penumbra_sends_the_bytes_tevclient_sends() {
    let (ours, theirs) = (penumbra_stream(), recorded());
    if let Some(i) = ours.iter().zip(&theirs).position(|(a, b)| a != b) {
        panic!(
            "first difference at byte {i}: penumbra {:?}, tevclient {:?}",
            &ours[i.saturating_sub(8)..(i + 8).min(ours.len())],
            &theirs[i.saturating_sub(8)..(i + 8).min(theirs.len())]
        );
    }
    assert_eq!(ours.len(), theirs.len(), "same prefix, different lengths");
}

/// penumbra's decoder reads tevclient's stream as the commands the script gave: the checks a
/// listening test makes (sizes, channels, blocks, values) rest on it.
#[test]
fn the_decoder_reads_tevclients_stream() {
    let bytes = recorded();
    let mut stream = bytes.as_slice();
    let mut packets = Vec::new();
    while let Some(p) = tev::read_packet(&mut stream, 1 << 24).unwrap() {
        packets.push(tev::decode(&p).unwrap());
    }
    assert_eq!(packets.len(), 1 + 1 + 4 + 1);
    assert_eq!(
        packets[0],
        Packet::Open {
            grab_focus: true,
            path: OPEN_PATH.into(),
            channel_selector: String::new()
        }
    );
    assert_eq!(
        packets[1],
        Packet::Create {
            grab_focus: true,
            name: NAME.into(),
            width: WIDTH as i32,
            height: HEIGHT as i32,
            channels: CHANNELS.iter().map(|c| c.to_string()).collect()
        }
    );
    assert_eq!(packets[6], Packet::Close { name: NAME.into() });
    let image = image();
    let mut seen = vec![0u32; WIDTH * HEIGHT];
    for p in &packets[2..6] {
        let Packet::Update {
            x,
            y,
            width,
            height,
            channels,
            ..
        } = p
        else {
            panic!("not an update: {p:?}")
        };
        assert_eq!(channels, &CHANNELS);
        let (x, y, w, h) = (*x as usize, *y as usize, *width as usize, *height as usize);
        for (c, _) in CHANNELS.iter().enumerate() {
            let values = p.channel_values(c).unwrap();
            for j in 0..h {
                for i in 0..w {
                    let want = image[((y + j) * WIDTH + x + i) * CHANNELS.len() + c];
                    assert_eq!(
                        values[j * w + i],
                        want,
                        "({}, {}) channel {c}",
                        x + i,
                        y + j
                    );
                }
            }
        }
        for j in y..y + h {
            for i in x..x + w {
                seen[j * WIDTH + i] += 1;
            }
        }
    }
    assert!(seen.iter().all(|&n| n == 1), "the blocks tile the image");
}
