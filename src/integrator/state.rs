//! The bytes of a progressive algorithm's state, for checkpoints: plain
//! little-endian numbers, read back with every count checked against the
//! bytes that remain before anything is allocated, so that a damaged file
//! is refused with a reason rather than trusted.

use crate::film::AovSum;
use glam::DVec3;

/// Writes a state.
#[derive(Default)]
pub struct StateWriter(pub Vec<u8>);

impl StateWriter {
    pub fn u32(&mut self, v: u32) {
        self.0.extend_from_slice(&v.to_le_bytes());
    }

    pub fn u64(&mut self, v: u64) {
        self.0.extend_from_slice(&v.to_le_bytes());
    }

    pub fn f32(&mut self, v: f32) {
        self.u32(v.to_bits());
    }

    pub fn f64(&mut self, v: f64) {
        self.u64(v.to_bits());
    }

    /// A count, then `f64`s.
    pub fn f64s(&mut self, v: &[f64]) {
        self.u64(v.len() as u64);
        for &x in v {
            self.f64(x);
        }
    }

    /// An auxiliary sum's nine numbers.
    pub fn aov(&mut self, a: &AovSum) {
        for v in [a.albedo.x, a.albedo.y, a.albedo.z, a.normal.x, a.normal.y, a.normal.z] {
            self.f64(v);
        }
        for v in [a.depth, a.count, a.steps] {
            self.f64(v);
        }
    }

    /// A count, then vectors.
    pub fn dvec3s(&mut self, v: &[DVec3]) {
        self.u64(v.len() as u64);
        for x in v {
            for c in x.to_array() {
                self.f64(c);
            }
        }
    }
}

/// Reads a state written by [`StateWriter`].
pub struct StateReader<'a> {
    bytes: &'a [u8],
    pos: usize,
}

impl<'a> StateReader<'a> {
    pub fn new(bytes: &'a [u8]) -> StateReader<'a> {
        StateReader { bytes, pos: 0 }
    }

    fn take<const N: usize>(&mut self) -> Result<[u8; N], String> {
        let end = self.pos.checked_add(N).filter(|&e| e <= self.bytes.len());
        let Some(end) = end else {
            return Err("the algorithm's state is truncated".into());
        };
        let out = self.bytes[self.pos..end].try_into().expect("N bytes");
        self.pos = end;
        Ok(out)
    }

    pub fn u32(&mut self) -> Result<u32, String> {
        Ok(u32::from_le_bytes(self.take()?))
    }

    pub fn u64(&mut self) -> Result<u64, String> {
        Ok(u64::from_le_bytes(self.take()?))
    }

    pub fn f32(&mut self) -> Result<f32, String> {
        Ok(f32::from_bits(self.u32()?))
    }

    pub fn f64(&mut self) -> Result<f64, String> {
        Ok(f64::from_bits(self.u64()?))
    }

    /// An auxiliary sum written by [`StateWriter::aov`].
    pub fn aov(&mut self) -> Result<AovSum, String> {
        let mut v = [0.0; 9];
        for x in &mut v {
            *x = self.f64()?;
        }
        Ok(AovSum {
            albedo: DVec3::new(v[0], v[1], v[2]),
            normal: DVec3::new(v[3], v[4], v[5]),
            depth: v[6],
            count: v[7],
            steps: v[8],
        })
    }

    /// A count of items of `item_bytes` bytes each, refused if the bytes
    /// left cannot hold them.
    pub fn count(&mut self, item_bytes: usize) -> Result<usize, String> {
        let n = self.u64()?;
        let left = (self.bytes.len() - self.pos) as u64;
        if n.checked_mul(item_bytes.max(1) as u64).is_none_or(|b| b > left) {
            return Err(format!("the algorithm's state claims {n} items, more than it holds"));
        }
        Ok(n as usize)
    }

    /// `f64`s written by [`StateWriter::f64s`]: exactly `expected` of them.
    pub fn f64s(&mut self, expected: usize) -> Result<Vec<f64>, String> {
        let n = self.count(8)?;
        if n != expected {
            return Err(format!(
                "the algorithm's state holds {n} values where {expected} belong"
            ));
        }
        (0..n).map(|_| self.f64()).collect()
    }

    /// Vectors written by [`StateWriter::dvec3s`]: exactly `expected`.
    pub fn dvec3s(&mut self, expected: usize) -> Result<Vec<DVec3>, String> {
        let n = self.count(24)?;
        if n != expected {
            return Err(format!(
                "the algorithm's state holds {n} pixels where {expected} belong"
            ));
        }
        (0..n)
            .map(|_| Ok(DVec3::new(self.f64()?, self.f64()?, self.f64()?)))
            .collect()
    }

    /// Fails unless every byte was read.
    pub fn finish(self) -> Result<(), String> {
        if self.pos == self.bytes.len() {
            Ok(())
        } else {
            Err("the algorithm's state has bytes left over".into())
        }
    }
}
