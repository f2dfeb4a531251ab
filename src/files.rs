//! Reading files: every file a render reads (scenes, includes, meshes,
//! buffers, textures, checkpoints) goes through [`read_limited`] (or
//! [`read_limited_gz`], which also decompresses `.gz` files within the same
//! limit), which never reads more than a limit, notes what it read inside
//! [`record_file_reads`] (a checkpoint lists those files so that a resume
//! notices an edited one), and words I/O errors briefly ([`io_reason`]).
//! The size limits of each kind of file are here, together.
//!
//! Format readers (`scene::native`, `scene::mitsuba`, `scene::pbrt`,
//! `scene::gltf`, `scene::obj`, `scene::ply`), image reading (`film::io`,
//! `texture`) and checkpoints (`render::checkpoint`) use this module; it
//! uses none of them.

use std::cell::RefCell;
use std::path::{Path, PathBuf};

/// Largest scene file read (native TOML, pbrt-v4, OBJ and MTL, glTF JSON),
/// in bytes.
pub const MAX_SCENE_BYTES: u64 = 1 << 30;
/// Largest Mitsuba XML file read, in bytes.
pub const MAX_XML_BYTES: u64 = 256 << 20;
/// Largest PLY file read, in bytes.
pub const MAX_PLY_BYTES: u64 = 1 << 34;
/// Largest GLB or external glTF buffer file read, in bytes (a GLB's own
/// length field cannot describe more).
pub const MAX_BUFFER_BYTES: u64 = 1 << 32;
/// Largest NanoVDB grid file read, in bytes (a grid's own bytes are
/// bounded again by [`crate::media::nanovdb::MAX_GRID_BYTES`]).
pub const MAX_NANOVDB_BYTES: u64 = 1 << 34;
/// Largest image file read, in bytes.
pub const MAX_IMAGE_FILE_BYTES: u64 = 1 << 32;

/// Reads at most `limit` bytes of a file: a longer file (or a device such as
/// `/dev/zero`, whose metadata say nothing of its length) is an error
/// rather than an unbounded allocation. Errors are short reasons. Inside
/// [`record_file_reads`], the file and a hash of its bytes are noted.
pub fn read_limited(path: &Path, limit: u64) -> std::result::Result<Vec<u8>, String> {
    use std::io::Read;
    let file = std::fs::File::open(path).map_err(|e| io_reason(&e))?;
    let mut bytes = Vec::new();
    file.take(limit.saturating_add(1))
        .read_to_end(&mut bytes)
        .map_err(|e| io_reason(&e))?;
    if bytes.len() as u64 > limit {
        return Err(format!("the file is larger than the limit of {limit} bytes"));
    }
    READ_LOG.with(|log| {
        if let Some(log) = log.borrow_mut().as_mut() {
            log.push(FileRead {
                path: std::fs::canonicalize(path).unwrap_or_else(|_| path.to_path_buf()),
                hash: content_hash(&bytes),
            });
        }
    });
    Ok(bytes)
}

/// Reads a file as [`read_limited`] does and, if its name ends in `.gz`,
/// decompresses it (every gzip member, as `gunzip` does): `limit` bounds
/// the decompressed bytes too, so a small file that inflates to far more
/// (a "gzip bomb") is an error when the limit is reached, not an
/// allocation without bound.
pub fn read_limited_gz(path: &Path, limit: u64) -> std::result::Result<Vec<u8>, String> {
    let bytes = read_limited(path, limit)?;
    if !is_gzip_name(path) {
        return Ok(bytes);
    }
    gunzip_limited(&bytes, limit)
}

/// Whether a file name ends in `.gz` (in any case): a gzip-compressed file.
pub fn is_gzip_name(path: &Path) -> bool {
    path.extension().is_some_and(|e| e.eq_ignore_ascii_case("gz"))
}

/// Decompresses gzip data, refusing to produce more than `limit` bytes; an
/// allocation that fails on the way is an error too, not an abort.
pub fn gunzip_limited(bytes: &[u8], limit: u64) -> std::result::Result<Vec<u8>, String> {
    use std::io::Read;
    let mut decoder = flate2::read::MultiGzDecoder::new(bytes);
    let mut out: Vec<u8> = Vec::new();
    let mut chunk = vec![0u8; 1 << 16];
    loop {
        let n = match decoder.read(&mut chunk) {
            Ok(0) => return Ok(out),
            Ok(n) => n,
            Err(e) if e.kind() == std::io::ErrorKind::Interrupted => continue,
            Err(e) => return Err(format!("the file is not valid gzip data ({e})")),
        };
        if (out.len() + n) as u64 > limit {
            return Err(format!(
                "the file decompresses to more than the limit of {limit} bytes (a gzip bomb, or a file too large to read)"
            ));
        }
        out.try_reserve(n).map_err(|_| {
            format!(
                "there is not enough memory to decompress the file (after {} bytes)",
                out.len()
            )
        })?;
        out.extend_from_slice(&chunk[..n]);
    }
}

/// A file that loading a scene read: its path (canonical where possible)
/// and a hash of its contents.
#[derive(Clone, Debug, PartialEq, Eq, PartialOrd, Ord, Hash)]
pub struct FileRead {
    /// Where.
    pub path: PathBuf,
    /// [`content_hash`] of the bytes read.
    pub hash: u64,
}

thread_local! {
    /// The files [`read_limited`] read on this thread inside
    /// [`record_file_reads`]; `None` outside.
    static READ_LOG: RefCell<Option<Vec<FileRead>>> = const { RefCell::new(None) };
}

/// Runs `f` and returns, with its result, every file it read through
/// [`read_limited`] on this thread (scene, includes, meshes, images), sorted,
/// each once. A checkpoint records them so that a resume notices any of
/// them edited, not only the scene file.
pub fn record_file_reads<T>(f: impl FnOnce() -> T) -> (T, Vec<FileRead>) {
    let outer = READ_LOG.with(|log| log.borrow_mut().replace(Vec::new()));
    let value = f();
    let mut files = READ_LOG
        .with(|log| std::mem::replace(&mut *log.borrow_mut(), outer))
        .unwrap_or_default();
    files.sort();
    files.dedup();
    // A nested recording's reads belong to the outer one too.
    READ_LOG.with(|log| {
        if let Some(outer) = log.borrow_mut().as_mut() {
            outer.extend(files.iter().cloned());
        }
    });
    (value, files)
}

/// A 64-bit hash of `bytes` for noticing edited files (not against an
/// adversary): FNV-1a's multiply-xor step over 8-byte words, so that a
/// gigabyte of mesh hashes in a fraction of a second, then the tail and the
/// length.
pub fn content_hash(bytes: &[u8]) -> u64 {
    const PRIME: u64 = 0x0000_0100_0000_01b3;
    let mut h: u64 = 0xcbf2_9ce4_8422_2325;
    let mut words = bytes.chunks_exact(8);
    for w in &mut words {
        h ^= u64::from_le_bytes(w.try_into().expect("8 bytes"));
        h = h.wrapping_mul(PRIME).rotate_left(29);
    }
    for &b in words.remainder() {
        h ^= b as u64;
        h = h.wrapping_mul(PRIME);
    }
    (h ^ bytes.len() as u64).wrapping_mul(PRIME)
}

/// A short reason for an I/O error ("file not found", …).
pub fn io_reason(e: &std::io::Error) -> String {
    match e.kind() {
        std::io::ErrorKind::NotFound => "file not found".into(),
        std::io::ErrorKind::PermissionDenied => "permission denied".into(),
        _ => e.to_string(),
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn gzip(data: &[u8]) -> Vec<u8> {
        use std::io::Write;
        let mut e = flate2::write::GzEncoder::new(Vec::new(), flate2::Compression::default());
        e.write_all(data).unwrap();
        e.finish().unwrap()
    }

    #[test]
    fn gzip_files_decompress_within_the_limit_and_bombs_stop_at_it() {
        // Every member of a file is read, as `cat a.gz b.gz` makes one.
        let mut two = gzip(b"hello, ");
        two.extend(gzip(b"world"));
        assert_eq!(gunzip_limited(&two, 12).unwrap(), b"hello, world");
        let e = gunzip_limited(&two, 11).unwrap_err();
        assert!(e.contains("decompresses to more than the limit of 11 bytes"), "{e}");
        assert!(
            gunzip_limited(b"plain text", 100)
                .unwrap_err()
                .contains("not valid gzip data")
        );
        let mut cut = gzip(b"a longer text, cut short before its end");
        cut.truncate(cut.len() - 6);
        assert!(gunzip_limited(&cut, 100).unwrap_err().contains("not valid gzip data"));

        // Bombs: one member of 8 MiB of zeros (8 KiB of gzip), and 1024
        // members of 1 MiB each (a GiB from 1 MiB): both stop at the limit.
        let single = {
            use std::io::Write;
            let mut e = flate2::write::GzEncoder::new(Vec::new(), flate2::Compression::default());
            for _ in 0..128 {
                e.write_all(&[0u8; 1 << 16]).unwrap();
            }
            e.finish().unwrap()
        };
        let member = gzip(&vec![0u8; 1 << 20]);
        let many: Vec<u8> = member.iter().copied().cycle().take(member.len() * 1024).collect();
        for bomb in [&single, &many] {
            assert!(bomb.len() < 2 << 20);
            let e = gunzip_limited(bomb, 1 << 20).unwrap_err();
            assert!(
                e.contains("decompresses to more than the limit of 1048576 bytes"),
                "{e}"
            );
        }

        // By name: only `.gz` files are decompressed, and the limit holds for
        // the file too.
        let dir = tempfile::tempdir().unwrap();
        let (plain, packed) = (dir.path().join("a.txt"), dir.path().join("a.txt.GZ"));
        std::fs::write(&plain, gzip(b"x")).unwrap();
        std::fs::write(&packed, gzip(b"x")).unwrap();
        assert_eq!(read_limited_gz(&plain, 100).unwrap(), gzip(b"x"));
        assert_eq!(read_limited_gz(&packed, 100).unwrap(), b"x");
        assert!(
            read_limited_gz(&packed, 4)
                .unwrap_err()
                .contains("larger than the limit of 4 bytes")
        );
    }

    #[test]
    fn file_reads_are_recorded_once_each_with_their_content() {
        let dir = tempfile::tempdir().unwrap();
        let (a, b) = (dir.path().join("a.txt"), dir.path().join("b.txt"));
        std::fs::write(&a, "first").unwrap();
        std::fs::write(&b, "second").unwrap();
        // Outside a recording nothing is noted.
        read_limited(&a, 100).unwrap();
        let ((), files) = record_file_reads(|| {
            read_limited(&b, 100).unwrap();
            let ((), inner) = record_file_reads(|| {
                read_limited(&a, 100).unwrap();
            });
            assert_eq!(inner.len(), 1);
            read_limited(&b, 100).unwrap();
            assert!(read_limited(&dir.path().join("missing"), 100).is_err());
        });
        let names: Vec<_> = files.iter().map(|f| f.path.file_name().unwrap().to_owned()).collect();
        assert_eq!(names, ["a.txt", "b.txt"], "sorted, once each, nested reads included");
        assert_eq!(files[0].hash, content_hash(b"first"));
        assert_eq!(files[1].hash, content_hash(b"second"));
        let ((), none) = record_file_reads(|| ());
        assert!(none.is_empty());
    }

    #[test]
    fn content_hash_tells_contents_apart() {
        let base: Vec<u8> = (0..1000u32).map(|i| (i * 7 % 251) as u8).collect();
        let h = content_hash(&base);
        assert_eq!(h, content_hash(&base.clone()));
        let mut seen = std::collections::HashSet::from([h]);
        for i in [0, 7, 8, 500, 999] {
            let mut edited = base.clone();
            edited[i] ^= 1;
            assert!(seen.insert(content_hash(&edited)), "a flipped bit at byte {i}");
        }
        // Length counts, zero bytes included; so does word order.
        assert!(seen.insert(content_hash(&base[..999])));
        assert!(seen.insert(content_hash(&[0u8; 16])));
        assert!(seen.insert(content_hash(&[0u8; 17])));
        let mut swapped = base.clone();
        swapped[..16].rotate_left(8);
        assert!(seen.insert(content_hash(&swapped)));
    }
}
