//! The network protocol of the tev image viewer (its "IPC"), as far as penumbra speaks it:
//! open an image file, create an image with named channels, update a block of its pixels,
//! close it. Written from tev's own description of its packets and checked byte for byte
//! against tev's Python client, `tevclient` (`tests/tev_protocol.rs`, with a stream that
//! client recorded).
//!
//! # The wire format
//!
//! A client opens a TCP connection to tev (by default port 14158) and writes packets, one
//! after another; tev never answers. Every number is little-endian. A packet is:
//!
//! - its total length in bytes, this field included: u32;
//! - its kind: one byte (see [`Kind`]);
//! - the kind's fields, in order, where a string is its UTF-8 bytes followed by one zero
//!   byte (so a string cannot contain a zero byte), a flag is one byte (1 or 0), and a
//!   count or coordinate is an i32.
//!
//! The kinds penumbra sends:
//!
//! | kind | byte | fields |
//! |---|---|---|
//! | open image | 7 | grab focus (flag), path (string: a file on tev's machine), channel selector (string, may be empty) |
//! | close image | 2 | image name (string) |
//! | create image | 4 | grab focus, image name, width, height, channel count (i32 each), then each channel name (string) |
//! | update image | 6 | grab focus, image name, channel count n, n channel names, x, y, width, height of the block (i32 each), n channel offsets (i64), n channel strides (i64), then the block's values (f32) |
//!
//! "Create image" makes a black image of that name (replacing one of the same name).
//! Channels named `layer.X` are shown as channel X of layer `layer`. "Update image" writes a
//! block of pixels of some of an existing image's channels: the value of channel c at the
//! block's pixel p (counted row by row from the block's top-left corner) is value number
//! offset_c + p · stride_c of the packet's values. penumbra sends pixels interleaved, as
//! `tevclient` does: offsets 0, 1, ..., n − 1 and every stride n, so the values run
//! pixel by pixel and, within a pixel, channel by channel. tev accepts blocks of any size;
//! penumbra cuts a whole-image update into blocks of [`TILE`]² pixels (the last ones in a
//! row or column smaller), row of blocks by row of blocks, each block left to right, as
//! `tevclient` cuts an image.
//!
//! Kinds 0, 3 and 5 are older forms of "open" and "update", 1 reloads an image from disk and
//! 8 draws vector graphics: penumbra sends none of them, and [`decode`] reads them as
//! [`Packet::Other`].

use std::io::Read;

/// tev's default port.
pub const DEFAULT_PORT: u16 = 14158;

/// The side of the blocks a whole-image update is cut into (`tevclient`'s).
pub const TILE: usize = 128;

/// The packet kinds (the byte after the length).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Kind {
    CloseImage = 2,
    CreateImage = 4,
    UpdateImage = 6,
    OpenImage = 7,
}

/// A packet that cannot be written (a name with a zero byte, sizes out of range) or read (a
/// malformed or truncated packet).
#[derive(Debug, Clone, PartialEq, Eq, thiserror::Error)]
#[error("tev protocol: {0}")]
pub struct ProtocolError(pub String);

fn err<T>(message: impl Into<String>) -> Result<T, ProtocolError> {
    Err(ProtocolError(message.into()))
}

/// Appends packets to a buffer: `begin` writes a length placeholder and the kind, `end`
/// fills in the length.
struct Writer<'a> {
    out: &'a mut Vec<u8>,
    start: usize,
}

impl<'a> Writer<'a> {
    fn begin(out: &'a mut Vec<u8>, kind: Kind) -> Self {
        let start = out.len();
        out.extend_from_slice(&[0; 4]);
        out.push(kind as u8);
        Writer { out, start }
    }

    fn flag(&mut self, b: bool) {
        self.out.push(b as u8);
    }

    fn string(&mut self, s: &str) -> Result<(), ProtocolError> {
        if s.as_bytes().contains(&0) {
            return err(format!("the name {s:?} contains a zero byte"));
        }
        self.out.extend_from_slice(s.as_bytes());
        self.out.push(0);
        Ok(())
    }

    fn i32(&mut self, v: usize, what: &str) -> Result<(), ProtocolError> {
        let v = i32::try_from(v)
            .map_err(|_| ProtocolError(format!("{what} {v} does not fit the protocol's i32")))?;
        self.out.extend_from_slice(&v.to_le_bytes());
        Ok(())
    }

    fn i64(&mut self, v: i64) {
        self.out.extend_from_slice(&v.to_le_bytes());
    }

    fn end(self) -> Result<(), ProtocolError> {
        let len = self.out.len() - self.start;
        match u32::try_from(len) {
            Ok(n) => {
                self.out[self.start..self.start + 4].copy_from_slice(&n.to_le_bytes());
                Ok(())
            }
            Err(_) => {
                self.out.truncate(self.start);
                err(format!(
                    "a packet of {len} bytes exceeds the protocol's 4 GiB"
                ))
            }
        }
    }
}

/// Appends an "open image" packet: tev loads the file at `path` (on tev's machine).
pub fn open_image(
    out: &mut Vec<u8>,
    path: &str,
    channel_selector: &str,
    grab_focus: bool,
) -> Result<(), ProtocolError> {
    let start = out.len();
    let mut w = Writer::begin(out, Kind::OpenImage);
    w.flag(grab_focus);
    let r = w.string(path).and_then(|_| w.string(channel_selector));
    finish(w, r, start)
}

/// Appends a "close image" packet.
pub fn close_image(out: &mut Vec<u8>, name: &str) -> Result<(), ProtocolError> {
    let start = out.len();
    let mut w = Writer::begin(out, Kind::CloseImage);
    let r = w.string(name);
    finish(w, r, start)
}

/// Appends a "create image" packet: a black image `width` × `height` with these channels.
pub fn create_image(
    out: &mut Vec<u8>,
    name: &str,
    grab_focus: bool,
    width: usize,
    height: usize,
    channels: &[&str],
) -> Result<(), ProtocolError> {
    let start = out.len();
    let mut w = Writer::begin(out, Kind::CreateImage);
    w.flag(grab_focus);
    let r = (|| {
        w.string(name)?;
        w.i32(width, "width")?;
        w.i32(height, "height")?;
        w.i32(channels.len(), "channel count")?;
        channels.iter().try_for_each(|c| w.string(c))
    })();
    finish(w, r, start)
}

/// A block of pixels: its top-left corner and size.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Block {
    pub x: usize,
    pub y: usize,
    pub width: usize,
    pub height: usize,
}

/// The blocks of [`TILE`]² pixels a `width` × `height` image is sent in, in `tevclient`'s
/// order: rows of blocks from the top, each left to right.
pub fn tiles(width: usize, height: usize) -> impl Iterator<Item = Block> {
    (0..height).step_by(TILE).flat_map(move |y| {
        (0..width).step_by(TILE).map(move |x| Block {
            x,
            y,
            width: TILE.min(width - x),
            height: TILE.min(height - y),
        })
    })
}

/// Appends an "update image" packet for `block` of an image whose values are `image`:
/// `image_width` pixels per row, each pixel `channels.len()` values in the order of
/// `channels` (interleaved, as sent).
pub fn update_image(
    out: &mut Vec<u8>,
    name: &str,
    grab_focus: bool,
    channels: &[&str],
    image: &[f32],
    image_width: usize,
    block: Block,
) -> Result<(), ProtocolError> {
    let n = channels.len();
    let row = image_width.checked_mul(n);
    let fits = row.and_then(|row| {
        let end_y = block.y.checked_add(block.height)?;
        let end_x = block.x.checked_add(block.width)?;
        (end_x <= image_width && end_y.checked_mul(row)? <= image.len()).then_some(row)
    });
    let row = match fits {
        Some(row) if n > 0 && block.width > 0 && block.height > 0 => row,
        _ => {
            return err(format!(
                "the block {block:?} of {n} channels is empty or outside an image of {} values \
                 and {image_width} pixels per row",
                image.len()
            ))
        }
    };
    let start = out.len();
    let mut w = Writer::begin(out, Kind::UpdateImage);
    w.flag(grab_focus);
    let r = (|| {
        w.string(name)?;
        w.i32(n, "channel count")?;
        channels.iter().try_for_each(|c| w.string(c))?;
        w.i32(block.x, "x")?;
        w.i32(block.y, "y")?;
        w.i32(block.width, "width")?;
        w.i32(block.height, "height")?;
        for c in 0..n {
            w.i64(c as i64);
        }
        for _ in 0..n {
            w.i64(n as i64);
        }
        w.out.reserve(block.width * block.height * n * 4);
        for y in block.y..block.y + block.height {
            let first = y * row + block.x * n;
            for v in &image[first..first + block.width * n] {
                w.out.extend_from_slice(&v.to_le_bytes());
            }
        }
        Ok(())
    })();
    finish(w, r, start)
}

/// Ends a packet, or removes what was written of it if a field failed.
fn finish(w: Writer, r: Result<(), ProtocolError>, start: usize) -> Result<(), ProtocolError> {
    match r {
        Ok(()) => w.end(),
        Err(e) => {
            w.out.truncate(start);
            Err(e)
        }
    }
}

/// A packet read back (for tests and tools that listen as tev does).
#[derive(Clone, Debug, PartialEq)]
pub enum Packet {
    Open {
        grab_focus: bool,
        path: String,
        channel_selector: String,
    },
    Close {
        name: String,
    },
    Create {
        grab_focus: bool,
        name: String,
        width: i32,
        height: i32,
        channels: Vec<String>,
    },
    Update {
        grab_focus: bool,
        name: String,
        channels: Vec<String>,
        x: i32,
        y: i32,
        width: i32,
        height: i32,
        offsets: Vec<i64>,
        strides: Vec<i64>,
        /// The packet's values, as sent (see [`Packet::channel_values`]).
        data: Vec<f32>,
    },
    /// A kind penumbra does not send.
    Other {
        kind: u8,
    },
}

impl Packet {
    /// An update's values of its channel number `c`, pixel by pixel (row by row), from its
    /// offsets and strides; `None` for another packet, a channel it lacks, or offsets and
    /// strides that reach past its values.
    pub fn channel_values(&self, c: usize) -> Option<Vec<f32>> {
        match self {
            Packet::Update {
                width,
                height,
                offsets,
                strides,
                data,
                ..
            } => {
                let (o, s) = (*offsets.get(c)?, *strides.get(c)?);
                let pixels = (*width as i64) * (*height as i64);
                (0..pixels)
                    .map(|p| {
                        let i = usize::try_from(o.checked_add(p.checked_mul(s)?)?).ok()?;
                        data.get(i).copied()
                    })
                    .collect()
            }
            _ => None,
        }
    }
}

/// Reads fields of one packet (bounds checked before every read).
struct Reader<'a> {
    bytes: &'a [u8],
    at: usize,
}

impl Reader<'_> {
    fn take(&mut self, n: usize) -> Result<&[u8], ProtocolError> {
        if self.bytes.len() - self.at < n {
            return err(format!(
                "the packet ends after {} bytes, inside a field",
                self.bytes.len()
            ));
        }
        self.at += n;
        Ok(&self.bytes[self.at - n..self.at])
    }

    fn flag(&mut self) -> Result<bool, ProtocolError> {
        Ok(self.take(1)?[0] == 1)
    }

    fn i32(&mut self) -> Result<i32, ProtocolError> {
        Ok(i32::from_le_bytes(
            self.take(4)?.try_into().unwrap_or([0; 4]),
        ))
    }

    fn count(&mut self, what: &str) -> Result<usize, ProtocolError> {
        let v = self.i32()?;
        usize::try_from(v).map_err(|_| ProtocolError(format!("negative {what} {v}")))
    }

    fn i64(&mut self) -> Result<i64, ProtocolError> {
        Ok(i64::from_le_bytes(
            self.take(8)?.try_into().unwrap_or([0; 8]),
        ))
    }

    fn string(&mut self) -> Result<String, ProtocolError> {
        let rest = &self.bytes[self.at..];
        let Some(end) = rest.iter().position(|&b| b == 0) else {
            return err("a string is not terminated before the packet ends");
        };
        self.at += end + 1;
        Ok(String::from_utf8_lossy(&rest[..end]).into_owned())
    }

    /// `count` strings, refusing a count the rest of the packet cannot hold (each string
    /// takes at least its terminating byte), before allocating.
    fn strings(&mut self, count: usize) -> Result<Vec<String>, ProtocolError> {
        if count > self.bytes.len() - self.at {
            return err(format!("{count} names do not fit the packet"));
        }
        (0..count).map(|_| self.string()).collect()
    }
}

/// Reads one whole packet (its length field included).
pub fn decode(bytes: &[u8]) -> Result<Packet, ProtocolError> {
    if bytes.len() < 5 {
        return err(format!("a packet of {} bytes is too short", bytes.len()));
    }
    let len = u32::from_le_bytes([bytes[0], bytes[1], bytes[2], bytes[3]]) as usize;
    if len != bytes.len() {
        return err(format!(
            "the packet says it has {len} bytes, it has {}",
            bytes.len()
        ));
    }
    let mut r = Reader { bytes, at: 5 };
    let packet = match bytes[4] {
        7 => Packet::Open {
            grab_focus: r.flag()?,
            path: r.string()?,
            channel_selector: r.string()?,
        },
        2 => Packet::Close { name: r.string()? },
        4 => {
            let grab_focus = r.flag()?;
            let name = r.string()?;
            let (width, height) = (r.i32()?, r.i32()?);
            let n = r.count("channel count")?;
            Packet::Create {
                grab_focus,
                name,
                width,
                height,
                channels: r.strings(n)?,
            }
        }
        6 => {
            let grab_focus = r.flag()?;
            let name = r.string()?;
            let n = r.count("channel count")?;
            let channels = r.strings(n)?;
            let (x, y, width, height) = (r.i32()?, r.i32()?, r.i32()?, r.i32()?);
            if n > (bytes.len() - r.at) / 16 {
                return err(format!(
                    "{n} channel offsets and strides do not fit the packet"
                ));
            }
            let offsets = (0..n).map(|_| r.i64()).collect::<Result<Vec<_>, _>>()?;
            let strides = (0..n).map(|_| r.i64()).collect::<Result<Vec<_>, _>>()?;
            let rest = &bytes[r.at..];
            if !rest.len().is_multiple_of(4) {
                return err(format!("{} bytes of values are not whole f32s", rest.len()));
            }
            let data = rest
                .chunks_exact(4)
                .map(|b| f32::from_le_bytes([b[0], b[1], b[2], b[3]]))
                .collect();
            r.at = bytes.len();
            Packet::Update {
                grab_focus,
                name,
                channels,
                x,
                y,
                width,
                height,
                offsets,
                strides,
                data,
            }
        }
        kind => return Ok(Packet::Other { kind }),
    };
    if r.at != bytes.len() {
        return err(format!(
            "{} bytes follow the last field of the packet",
            bytes.len() - r.at
        ));
    }
    Ok(packet)
}

/// Reads the next packet's bytes from a stream: `None` at the end of the stream (between
/// packets). A packet longer than `max_bytes` is refused before anything is allocated for it.
pub fn read_packet(r: &mut impl Read, max_bytes: usize) -> std::io::Result<Option<Vec<u8>>> {
    let mut len = [0u8; 4];
    let mut got = 0;
    while got < 4 {
        match r.read(&mut len[got..]) {
            Ok(0) if got == 0 => return Ok(None),
            Ok(0) => return Err(std::io::ErrorKind::UnexpectedEof.into()),
            Ok(k) => got += k,
            Err(e) if e.kind() == std::io::ErrorKind::Interrupted => {}
            Err(e) => return Err(e),
        }
    }
    let n = u32::from_le_bytes(len) as usize;
    if !(5..=max_bytes).contains(&n) {
        return Err(std::io::Error::other(format!(
            "a packet of {n} bytes (at most {max_bytes}, at least 5)"
        )));
    }
    let mut bytes = vec![0u8; n];
    bytes[..4].copy_from_slice(&len);
    r.read_exact(&mut bytes[4..])?;
    Ok(Some(bytes))
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Every packet kind reads back as written, and its length field is its length.
    #[test]
    fn packets_read_back_as_written() {
        let (w, h) = (3usize, 2usize);
        let image: Vec<f32> = (0..w * h * 2).map(|i| i as f32 * 0.5 - 1.0).collect();
        let mut out = Vec::new();
        open_image(&mut out, "/a/b.exr", "R", true).unwrap();
        close_image(&mut out, "img").unwrap();
        create_image(&mut out, "img", false, w, h, &["R", "l.G"]).unwrap();
        let block = Block {
            x: 1,
            y: 0,
            width: 2,
            height: 2,
        };
        update_image(&mut out, "img", false, &["R", "l.G"], &image, w, block).unwrap();
        let mut stream = out.as_slice();
        let mut packets = Vec::new();
        while let Some(p) = read_packet(&mut stream, 1 << 20).unwrap() {
            packets.push(decode(&p).unwrap());
        }
        assert_eq!(packets.len(), 4);
        assert_eq!(
            packets[0],
            Packet::Open {
                grab_focus: true,
                path: "/a/b.exr".into(),
                channel_selector: "R".into()
            }
        );
        assert_eq!(packets[1], Packet::Close { name: "img".into() });
        assert_eq!(
            packets[2],
            Packet::Create {
                grab_focus: false,
                name: "img".into(),
                width: 3,
                height: 2,
                channels: vec!["R".into(), "l.G".into()]
            }
        );
        // pixels (1,0), (2,0), (1,1), (2,1) of channel 1: image[2·(x + 3y) + 1]
        let want: Vec<f32> = [(1, 0), (2, 0), (1, 1), (2, 1)]
            .iter()
            .map(|&(x, y)| image[2 * (x + 3 * y) + 1])
            .collect();
        assert_eq!(packets[3].channel_values(1).unwrap(), want);
    }

    #[test]
    fn bad_input_is_an_error_and_leaves_no_partial_packet() {
        let mut out = vec![9u8];
        assert!(create_image(&mut out, "a\0b", true, 1, 1, &["R"]).is_err());
        assert!(create_image(&mut out, "a", true, 1 << 31, 1, &["R"]).is_err());
        let block = Block {
            x: 1,
            y: 0,
            width: 2,
            height: 1,
        };
        assert!(update_image(&mut out, "a", true, &["R"], &[0.0; 2], 2, block).is_err());
        assert_eq!(out, [9]);
        // truncated, overlong, lying about its length, unterminated
        let mut good = Vec::new();
        create_image(&mut good, "a", true, 1, 1, &["R"]).unwrap();
        assert!(decode(&good[..good.len() - 1]).is_err());
        let mut long = good.clone();
        long.push(0);
        assert!(decode(&long).is_err());
        let mut huge = good.clone();
        huge[16..20].copy_from_slice(&i32::MAX.to_le_bytes()); // channel count
        assert!(decode(&huge).is_err());
        assert!(read_packet(&mut &[255u8, 255, 255, 127][..], 1 << 20).is_err());
    }

    #[test]
    fn tiles_cover_an_image_once_in_tevclient_order() {
        let t: Vec<Block> = tiles(300, 129).collect();
        assert_eq!(t.len(), 6);
        assert_eq!(
            t[2],
            Block {
                x: 256,
                y: 0,
                width: 44,
                height: 128
            }
        );
        assert_eq!(
            t[3],
            Block {
                x: 0,
                y: 128,
                width: 128,
                height: 1
            }
        );
        let area: usize = t.iter().map(|b| b.width * b.height).sum();
        assert_eq!(area, 300 * 129);
    }
}
