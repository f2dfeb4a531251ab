//! A live preview in the tev image viewer (github.com/Tom94/tev), as
//! pbrt-v4's `--display-server`: the image, and each auxiliary image as a
//! channel group of its own, sent over tev's TCP protocol after the passes
//! of a render.
//!
//! tev's packets are a little-endian u32 length (counting itself), a type
//! byte and the fields; strings end with a NUL. trazo sends two kinds:
//! create image (type 4: grab focus, name, width, height, channel count,
//! channel names) when it connects, and update image (type 6, tev's
//! version 3: grab focus, name, channel count and names, x, y, width,
//! height, a u64 offset and stride per channel into the f32 values that
//! follow) for every tile of [`TILE`]² pixels of a frame.
//!
//! Sending happens on a thread of its own, so that a slow or lost viewer
//! never stops or slows the render: a frame offered while the previous one
//! is still being sent is dropped (the next one supersedes it), a lost
//! connection is warned about once and tried again with the next frame.

use crate::color::Rgb;
use std::io::Write;
use std::net::{TcpStream, ToSocketAddrs};
use std::sync::Arc;
use std::sync::atomic::{AtomicUsize, Ordering};
use std::sync::mpsc::{Receiver, SyncSender, sync_channel};
use std::thread::JoinHandle;
use std::time::Duration;

/// Packet types of tev's protocol.
pub const CREATE_IMAGE: u8 = 4;
/// Update image, version 3 (with channel offsets and strides).
pub const UPDATE_IMAGE_V3: u8 = 6;

/// Side of the tiles a frame is sent in.
pub const TILE: u32 = 128;

/// How long a connection attempt may take.
const CONNECT_TIMEOUT: Duration = Duration::from_secs(2);
/// How long one write may block before the viewer counts as lost.
const WRITE_TIMEOUT: Duration = Duration::from_secs(10);

/// What a frame shows: named channels of equal size, pixel by pixel.
#[derive(Clone, Debug)]
pub struct Frame {
    /// Width in pixels.
    pub width: u32,
    /// Height in pixels.
    pub height: u32,
    /// Channel names (`R`, `G`, `B`, `albedo.R`, …): tev groups the
    /// channels by the part before the dot.
    pub channels: Vec<String>,
    /// `channels.len()` values per pixel, rows from the top.
    pub values: Vec<f32>,
}

impl Frame {
    /// A frame of an RGB image (`R`, `G`, `B`) and of further images whose
    /// channels are named `GROUP.R`, `GROUP.G`, `GROUP.B` (or `GROUP.Z`
    /// for a one-channel image such as depth).
    pub fn new(width: u32, height: u32, images: &[(&str, &[Rgb], usize)]) -> Frame {
        let mut channels = Vec::new();
        for &(group, _, n) in images {
            let names: &[&str] = if n == 1 { &["Z"] } else { &["R", "G", "B"] };
            for name in names {
                channels.push(if group.is_empty() {
                    name.to_string()
                } else {
                    format!("{group}.{name}")
                });
            }
        }
        let pixels = width as usize * height as usize;
        let mut values = Vec::with_capacity(pixels * channels.len());
        for i in 0..pixels {
            for &(_, image, n) in images {
                let p = image[i];
                values.extend_from_slice(&[p.x, p.y, p.z][..n]);
            }
        }
        Frame {
            width,
            height,
            channels,
            values,
        }
    }
}

/// Appends a packet of `kind` with the fields `write` appends, prefixed
/// with its length.
fn packet(out: &mut Vec<u8>, kind: u8, write: impl FnOnce(&mut Vec<u8>)) {
    let start = out.len();
    out.extend_from_slice(&[0; 4]);
    out.push(kind);
    write(out);
    let len = (out.len() - start) as u32;
    out[start..start + 4].copy_from_slice(&len.to_le_bytes());
}

/// A NUL-terminated string (NULs inside are dropped: tev cannot take them).
fn put_str(out: &mut Vec<u8>, s: &str) {
    out.extend(s.bytes().filter(|&b| b != 0));
    out.push(0);
}

/// The create-image packet for a frame named `name`.
pub fn create_packet(name: &str, frame: &Frame) -> Vec<u8> {
    let mut out = Vec::new();
    packet(&mut out, CREATE_IMAGE, |b| {
        b.push(0); // Do not grab the focus.
        put_str(b, name);
        b.extend_from_slice(&(frame.width as i32).to_le_bytes());
        b.extend_from_slice(&(frame.height as i32).to_le_bytes());
        b.extend_from_slice(&(frame.channels.len() as i32).to_le_bytes());
        for c in &frame.channels {
            put_str(b, c);
        }
    });
    out
}

/// The update-image packets of a whole frame, tile by tile, appended to `out`.
pub fn update_packets(name: &str, frame: &Frame, out: &mut Vec<u8>) {
    let n = frame.channels.len();
    for y0 in (0..frame.height).step_by(TILE as usize) {
        for x0 in (0..frame.width).step_by(TILE as usize) {
            let (w, h) = (TILE.min(frame.width - x0), TILE.min(frame.height - y0));
            packet(out, UPDATE_IMAGE_V3, |b| {
                b.push(0);
                put_str(b, name);
                b.extend_from_slice(&(n as i32).to_le_bytes());
                for c in &frame.channels {
                    put_str(b, c);
                }
                for v in [x0, y0, w, h] {
                    b.extend_from_slice(&(v as i32).to_le_bytes());
                }
                // Interleaved: channel c of pixel p at c + p·n.
                for c in 0..n {
                    b.extend_from_slice(&(c as u64).to_le_bytes());
                }
                for _ in 0..n {
                    b.extend_from_slice(&(n as u64).to_le_bytes());
                }
                for y in y0..y0 + h {
                    let row = (y as usize * frame.width as usize + x0 as usize) * n;
                    for v in &frame.values[row..row + w as usize * n] {
                        b.extend_from_slice(&v.to_le_bytes());
                    }
                }
            });
        }
    }
}

/// A connection to a tev viewer, fed from the render's thread and written
/// on a thread of its own.
pub struct Display {
    frames: Option<SyncSender<Frame>>,
    sender: Option<JoinHandle<()>>,
    /// Frames handed over and not yet sent (or given up).
    pending: Arc<AtomicUsize>,
}

impl Display {
    /// Starts sending to the viewer at `address` (HOST:PORT) the frames
    /// given to [`Display::offer`], as an image named `name`. Connecting
    /// happens on the sending thread: a viewer that is not there yet is
    /// tried again with each frame.
    pub fn start(address: &str, name: &str) -> Display {
        // One frame in waiting at most: a newer one is dropped while the
        // sender is busy (the render goes on either way).
        let (frames, inbox) = sync_channel::<Frame>(1);
        let (address, name) = (address.to_string(), name.to_string());
        let pending = Arc::new(AtomicUsize::new(0));
        let done = Arc::clone(&pending);
        let sender = std::thread::Builder::new()
            .name("trazo-display".into())
            .spawn(move || send_frames(&address, &name, inbox, &done))
            .ok();
        Display {
            frames: sender.is_some().then_some(frames),
            sender,
            pending,
        }
    }

    /// Whether a frame offered now would be sent (the sender is not busy):
    /// lets the caller skip making a frame that would be dropped.
    pub fn ready(&self) -> bool {
        self.frames.is_some() && self.pending.load(Ordering::Acquire) == 0
    }

    /// Hands a frame to the sender, unless it is still busy with an
    /// earlier one; never blocks.
    pub fn offer(&self, frame: Frame) {
        if let Some(f) = &self.frames {
            self.pending.fetch_add(1, Ordering::AcqRel);
            if f.try_send(frame).is_err() {
                self.pending.fetch_sub(1, Ordering::AcqRel);
            }
        }
    }

    /// Sends `frame` as the last one, waiting for the sender to finish with
    /// what it has, so that the viewer ends with the written image.
    pub fn finish(mut self, frame: Frame) {
        if let Some(f) = self.frames.take() {
            let _ = f.send(frame);
        }
        if let Some(t) = self.sender.take() {
            let _ = t.join();
        }
    }
}

/// The sending thread: connects when it has a frame and no connection,
/// sends it, and on any error warns (once until it works again) and drops
/// the connection.
fn send_frames(address: &str, name: &str, inbox: Receiver<Frame>, pending: &AtomicUsize) {
    let mut link = Link::default();
    for frame in inbox {
        link.send(address, name, &frame);
        pending.fetch_sub(1, Ordering::AcqRel);
    }
}

/// The sending thread's connection and what it told the viewer.
#[derive(Default)]
struct Link {
    stream: Option<TcpStream>,
    warned: bool,
    /// The shape of the image created on the viewer.
    created: Option<(u32, u32, Vec<String>)>,
}

impl Link {
    fn send(&mut self, address: &str, name: &str, frame: &Frame) {
        if self.stream.is_none() {
            match connect(address) {
                Ok(s) => {
                    if self.warned {
                        eprintln!("display server {address}: connected again");
                    }
                    self.stream = Some(s);
                    self.created = None;
                    self.warned = false;
                }
                Err(e) => {
                    if !self.warned {
                        eprintln!(
                            "warning: display server {address}: {e}; the render goes on, and trazo tries again after each pass"
                        );
                        self.warned = true;
                    }
                    return;
                }
            }
        }
        let s = self.stream.as_mut().expect("connected above");
        let mut bytes = Vec::new();
        let shape = (frame.width, frame.height, frame.channels.clone());
        if self.created.as_ref() != Some(&shape) {
            bytes = create_packet(name, frame);
        }
        update_packets(name, frame, &mut bytes);
        match s.write_all(&bytes).and_then(|()| s.flush()) {
            Ok(()) => self.created = Some(shape),
            Err(e) => {
                if !self.warned {
                    eprintln!(
                        "warning: display server {address}: the connection was lost ({e}); the render goes on, and trazo tries again after each pass"
                    );
                    self.warned = true;
                }
                self.stream = None;
            }
        }
    }
}

fn connect(address: &str) -> Result<TcpStream, String> {
    let addrs: Vec<_> = address
        .to_socket_addrs()
        .map_err(|e| format!("cannot resolve the address: {e}"))?
        .collect();
    let mut last = String::from("no address to connect to");
    for a in addrs {
        match TcpStream::connect_timeout(&a, CONNECT_TIMEOUT) {
            Ok(s) => {
                let _ = s.set_write_timeout(Some(WRITE_TIMEOUT));
                let _ = s.set_nodelay(true);
                return Ok(s);
            }
            Err(e) => last = format!("cannot connect: {e}"),
        }
    }
    Err(last)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn packets_follow_tevs_layout() {
        let img = [Rgb::new(1.0, 2.0, 3.0), Rgb::new(4.0, 5.0, 6.0)];
        let depth = [Rgb::splat(7.0), Rgb::splat(8.0)];
        let frame = Frame::new(2, 1, &[("", &img, 3), ("depth", &depth, 1)]);
        assert_eq!(frame.channels, ["R", "G", "B", "depth.Z"]);
        assert_eq!(frame.values, [1.0, 2.0, 3.0, 7.0, 4.0, 5.0, 6.0, 8.0]);
        let c = create_packet("a", &frame);
        let len = u32::from_le_bytes(c[..4].try_into().unwrap()) as usize;
        assert_eq!(len, c.len());
        assert_eq!(&c[4..8], &[CREATE_IMAGE, 0, b'a', 0]);
        assert_eq!(&c[8..12], &2i32.to_le_bytes());
        assert!(c.ends_with(b"R\0G\0B\0depth.Z\0"));
        let mut u = Vec::new();
        update_packets("a", &frame, &mut u);
        assert_eq!(u32::from_le_bytes(u[..4].try_into().unwrap()) as usize, u.len());
        assert_eq!(u[4], UPDATE_IMAGE_V3);
        // The values close the packet: 8 floats.
        let tail: Vec<f32> = u[u.len() - 32..]
            .chunks(4)
            .map(|b| f32::from_le_bytes(b.try_into().unwrap()))
            .collect();
        assert_eq!(tail, frame.values);
    }
}
