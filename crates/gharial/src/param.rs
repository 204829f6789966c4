//! Parameters that a shared, immutable model can still change between solves (targets,
//! weights), without locks and without reallocation: the receding-horizon loop of MPC
//! updates them while the solver's data stays in place.

use std::sync::atomic::{AtomicU64, Ordering};

/// A fixed-size vector of `f64` that can be read and written through `&self`.
///
/// Reads and writes of each entry are atomic; a reader running concurrently with a
/// writer may see a mix of old and new entries, so update parameters between solves.
pub struct ParamVec {
    values: Box<[AtomicU64]>,
}

impl ParamVec {
    /// A parameter vector holding `values`.
    pub fn new(values: &[f64]) -> Self {
        Self {
            values: values.iter().map(|v| AtomicU64::new(v.to_bits())).collect(),
        }
    }

    /// Number of entries.
    pub fn len(&self) -> usize {
        self.values.len()
    }

    /// Whether the vector is empty.
    pub fn is_empty(&self) -> bool {
        self.values.is_empty()
    }

    /// Entry `i`.
    pub fn get(&self, i: usize) -> f64 {
        f64::from_bits(self.values[i].load(Ordering::Relaxed))
    }

    /// Sets entry `i`.
    pub fn set(&self, i: usize, v: f64) {
        self.values[i].store(v.to_bits(), Ordering::Relaxed);
    }

    /// The entries in order (one pass, no index checks).
    pub fn iter(&self) -> impl ExactSizeIterator<Item = f64> + '_ {
        self.values.iter().map(|v| f64::from_bits(v.load(Ordering::Relaxed)))
    }

    /// Copies all entries into `out` (`out.len() == self.len()`).
    pub fn read(&self, out: &mut [f64]) {
        for (o, v) in out.iter_mut().zip(self.values.iter()) {
            *o = f64::from_bits(v.load(Ordering::Relaxed));
        }
    }

    /// Overwrites all entries from `values`.
    ///
    /// # Errors
    /// If the length differs.
    pub fn write(&self, values: &[f64]) -> crate::Result<()> {
        crate::error::check_dim("parameter vector", self.len(), values.len())?;
        for (a, v) in self.values.iter().zip(values) {
            a.store(v.to_bits(), Ordering::Relaxed);
        }
        Ok(())
    }

    /// The entries as an owned vector.
    pub fn to_vec(&self) -> Vec<f64> {
        let mut v = vec![0.0; self.len()];
        self.read(&mut v);
        v
    }
}

/// The values (not their bits): `ParamVec([-0.05, 0.05])`.
impl std::fmt::Debug for ParamVec {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_tuple("ParamVec").field(&self.to_vec()).finish()
    }
}

impl Clone for ParamVec {
    fn clone(&self) -> Self {
        Self::new(&self.to_vec())
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn debug_shows_the_values() {
        assert_eq!(format!("{:?}", ParamVec::new(&[-0.05, 2.0])), "ParamVec([-0.05, 2.0])");
    }

    #[test]
    fn read_write_roundtrip() {
        let p = ParamVec::new(&[1.0, -2.5, 3.0]);
        assert_eq!(p.to_vec(), vec![1.0, -2.5, 3.0]);
        p.set(1, 7.0);
        assert_eq!(p.get(1), 7.0);
        p.write(&[0.0, 0.5, f64::MIN_POSITIVE]).unwrap();
        assert_eq!(p.to_vec(), vec![0.0, 0.5, f64::MIN_POSITIVE]);
        assert_eq!(p.iter().collect::<Vec<_>>(), p.to_vec());
        assert_eq!(p.iter().len(), 3);
        assert!(p.write(&[1.0]).is_err());
    }
}
