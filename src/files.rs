//! Reading files: every file a render reads (scenes, includes, meshes,
//! buffers, textures, checkpoints) goes through [`read_limited`], which
//! never reads more than a limit, notes what it read inside
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
