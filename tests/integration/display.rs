//! `trazo render --display-server`: a small server that speaks tev's
//! protocol decodes what trazo sends, and the last update must be the
//! image written; a viewer that is missing or goes away must not stop the
//! render.

use std::collections::HashMap;
use std::io::Read;
use std::net::TcpListener;
use std::path::Path;
use trazo::film::io::read_image;

/// An image in the viewer: width, height and channels by name.
type ViewerImage = (u32, u32, HashMap<String, Vec<f32>>);

/// The images a tev viewer holds, by name.
#[derive(Default, Debug)]
struct Viewer {
    images: HashMap<String, ViewerImage>,
    creates: usize,
    updates: usize,
}

struct Fields<'a>(&'a [u8]);

impl Fields<'_> {
    fn take(&mut self, n: usize) -> &[u8] {
        let (a, b) = self.0.split_at(n);
        self.0 = b;
        a
    }
    fn u8(&mut self) -> u8 {
        self.take(1)[0]
    }
    fn i32(&mut self) -> i32 {
        i32::from_le_bytes(self.take(4).try_into().unwrap())
    }
    fn u64(&mut self) -> u64 {
        u64::from_le_bytes(self.take(8).try_into().unwrap())
    }
    fn string(&mut self) -> String {
        let end = self.0.iter().position(|&b| b == 0).expect("a NUL-terminated string");
        let s = String::from_utf8(self.0[..end].to_vec()).unwrap();
        self.0 = &self.0[end + 1..];
        s
    }
}

impl Viewer {
    /// Applies one packet (without its length), as tev does.
    fn apply(&mut self, packet: &[u8]) {
        let mut f = Fields(packet);
        match f.u8() {
            4 => {
                let _focus = f.u8();
                let name = f.string();
                let (w, h, n) = (f.i32() as u32, f.i32() as u32, f.i32());
                let channels = (0..n).map(|_| (f.string(), vec![0.0; (w * h) as usize])).collect();
                assert!(f.0.is_empty(), "trailing bytes in create image");
                self.images.insert(name, (w, h, channels));
                self.creates += 1;
            }
            6 => {
                let _focus = f.u8();
                let name = f.string();
                let n = f.i32() as usize;
                let names: Vec<String> = (0..n).map(|_| f.string()).collect();
                let (x, y, w, h) = (f.i32() as u32, f.i32() as u32, f.i32() as u32, f.i32() as u32);
                let offsets: Vec<u64> = (0..n).map(|_| f.u64()).collect();
                let strides: Vec<u64> = (0..n).map(|_| f.u64()).collect();
                let data: Vec<f32> =
                    f.0.chunks(4)
                        .map(|b| f32::from_le_bytes(b.try_into().unwrap()))
                        .collect();
                let (iw, ih, channels) = self.images.get_mut(&name).expect("an update of a created image");
                assert!(x + w <= *iw && y + h <= *ih, "a tile outside the image");
                for (c, channel) in names.iter().enumerate() {
                    let values = channels.get_mut(channel).expect("a created channel");
                    for ty in 0..h {
                        for tx in 0..w {
                            let p = (ty * w + tx) as u64;
                            values[((y + ty) * *iw + x + tx) as usize] = data[(offsets[c] + p * strides[c]) as usize];
                        }
                    }
                }
                self.updates += 1;
            }
            other => panic!("unexpected packet type {other}"),
        }
    }

    /// Reads packets from one connection until it closes.
    fn serve(&mut self, stream: &mut impl Read) {
        loop {
            let mut len = [0u8; 4];
            if stream.read_exact(&mut len).is_err() {
                return;
            }
            let len = u32::from_le_bytes(len) as usize;
            assert!(len > 5, "a packet of {len} bytes");
            let mut packet = vec![0; len - 4];
            stream.read_exact(&mut packet).unwrap();
            self.apply(&packet);
        }
    }
}

fn trazo(dir: &Path) -> assert_cmd::Command {
    let mut c = assert_cmd::Command::cargo_bin("trazo").unwrap();
    c.current_dir(dir);
    c
}

#[test]
fn the_last_update_is_the_written_image_with_its_auxiliary_images() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let listener = TcpListener::bind("127.0.0.1:0").unwrap();
    let address = listener.local_addr().unwrap().to_string();
    let server = std::thread::spawn(move || {
        let mut viewer = Viewer::default();
        // trazo connects once (and again only after an error).
        let (mut stream, _) = listener.accept().unwrap();
        viewer.serve(&mut stream);
        viewer
    });
    // 150 pixels wide: tiles of 128 and 22; an exposure, which the float
    // file and the viewer's image both get.
    trazo(d)
        .args([
            "render",
            "--width",
            "150",
            "--height",
            "40",
            "--spp",
            "8",
            "--aov",
            "albedo,depth",
        ])
        .args(["--exposure", "1"])
        .args(["--display-server", &address, "-q", "-o", "out.pfm"])
        .assert()
        .success();
    let viewer = server.join().unwrap();
    assert_eq!(viewer.creates, 1, "{viewer:?}");
    assert!(
        viewer.updates >= 2 * 2,
        "at least two frames of two tiles: {}",
        viewer.updates
    );
    let (w, h, channels) = &viewer.images["out.pfm"];
    assert_eq!((*w, *h), (150, 40));
    let mut names: Vec<&str> = channels.keys().map(String::as_str).collect();
    names.sort_unstable();
    assert_eq!(names, ["B", "G", "R", "albedo.B", "albedo.G", "albedo.R", "depth.Z"]);
    let image = read_image(&d.join("out.pfm")).unwrap();
    let albedo = read_image(&d.join("out.albedo.exr")).unwrap();
    let depth = read_image(&d.join("out.depth.exr")).unwrap();
    for (i, p) in image.pixels.iter().enumerate() {
        assert_eq!(
            [channels["R"][i], channels["G"][i], channels["B"][i]],
            [p.x, p.y, p.z],
            "pixel {i}"
        );
        let a = albedo.pixels[i];
        assert_eq!(
            [
                channels["albedo.R"][i],
                channels["albedo.G"][i],
                channels["albedo.B"][i]
            ],
            [a.x, a.y, a.z]
        );
        assert_eq!(channels["depth.Z"][i], depth.pixels[i].x);
    }
}

#[test]
fn a_missing_or_lost_viewer_does_not_stop_the_render() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    // Nobody listens on this port any more.
    let address = {
        let l = TcpListener::bind("127.0.0.1:0").unwrap();
        l.local_addr().unwrap().to_string()
    };
    let out = trazo(d)
        .args(["render", "--width", "16", "--height", "16", "--spp", "8"])
        .args(["--display-server", &address, "-q", "-o", "a.png"])
        .output()
        .unwrap();
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(out.status.success(), "{err}");
    assert!(d.join("a.png").exists());
    assert_eq!(err.matches("warning: display server").count(), 1, "one warning: {err}");
    // A viewer that hangs up after the first packet.
    let listener = TcpListener::bind("127.0.0.1:0").unwrap();
    let address = listener.local_addr().unwrap().to_string();
    let server = std::thread::spawn(move || {
        let (mut s, _) = listener.accept().unwrap();
        let mut first = [0u8; 64];
        let _ = s.read(&mut first);
    });
    let out = trazo(d)
        .args(["render", "--width", "256", "--height", "256", "--spp", "16"])
        .args(["--display-server", &address, "-q", "-o", "b.png"])
        .output()
        .unwrap();
    server.join().unwrap();
    assert!(out.status.success(), "{}", String::from_utf8_lossy(&out.stderr));
    assert!(d.join("b.png").exists());
    // An address that is not one is bad input; a host that does not
    // resolve is a viewer that is not there.
    let out = trazo(d)
        .args(["render", "--display-server", "no-port-here", "-o", "c.png"])
        .output()
        .unwrap();
    assert_eq!(out.status.code(), Some(2));
    assert!(String::from_utf8_lossy(&out.stderr).contains("expected HOST:PORT"));
    let out = trazo(d)
        .args(["render", "--width", "8", "--height", "8", "--spp", "1"])
        .args(["--display-server", "no-such-host.invalid:14158", "-q", "-o", "c.png"])
        .output()
        .unwrap();
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(out.status.success() && err.contains("cannot resolve"), "{err}");
}
