//! A memo of fitted start states and of runs' scores, so a model simulated again on the same
//! record does not fit its start, or run at all, again.
//!
//! A diagnosis scores the same model on the same records many times over (the start model under
//! every candidate's refit, the judge and the null; a refit kept by two decisions), and fitting
//! the start state is most of a run's cost ([`crate::choose_initial_state`]: two
//! Levenberg–Marquardt fits of a few dozen simulations of the first periods). The fit is a pure
//! function of the model's equations, the columns the run reads, and the options, so its result
//! is kept under a hash of all of them and a later run from the same inputs starts from it: the
//! same state to the bit, without the fit. So is the whole run, so its score on the record (the
//! R-MSE of each DOF, [`crate::r_mse_on_record`]) is kept under the same key: a score asked for
//! again is the first run's, without the run. Only the start state and the scores are kept (a few
//! numbers per run), so the memo costs no memory worth counting; a trajectory asked for again is
//! integrated again.

use std::collections::{HashMap, VecDeque};
use std::sync::{Mutex, OnceLock};

use crate::Result;

/// Entries the memo holds before the oldest is forgotten: far more than the distinct
/// model–record pairs of one diagnosis (about a hundred), at about a hundred bytes each.
const CAPACITY: usize = 4096;

/// The hash of everything a start-state fit reads: two independent 64-bit lanes.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub(crate) struct StartKey([u64; 2]);

/// Builds a [`StartKey`] from words and byte strings. Each lane is a chain of bijections of
/// its state for a given word (an xor, a multiplication by an odd constant, a rotation), so
/// two inputs that differ in one word, or in their lengths, never share a lane's state; inputs
/// that differ in several words collide with probability about 2⁻¹²⁸.
pub(crate) struct KeyHasher {
    a: u64,
    b: u64,
    n: u64,
}

impl KeyHasher {
    pub(crate) fn new() -> Self {
        Self {
            a: 0x243F_6A88_85A3_08D3,
            b: 0x1319_8A2E_0370_7344,
            n: 0,
        }
    }

    #[inline]
    fn word(&mut self, w: u64) {
        self.a = (self.a ^ w)
            .wrapping_mul(0x9E37_79B9_7F4A_7C15)
            .rotate_left(29);
        self.b = (self.b.rotate_left(23) ^ w).wrapping_mul(0xD6E8_FEB8_6659_FD93);
        self.n = self.n.wrapping_add(1);
    }

    /// Adds a slice of values, bit for bit, and its length.
    pub(crate) fn floats(&mut self, v: &[f64]) -> &mut Self {
        self.word(v.len() as u64);
        for x in v {
            self.word(x.to_bits());
        }
        self
    }

    /// Adds a string's bytes and its length.
    pub(crate) fn text(&mut self, s: &str) -> &mut Self {
        self.word(s.len() as u64);
        for chunk in s.as_bytes().chunks(8) {
            let mut w = [0u8; 8];
            w[..chunk.len()].copy_from_slice(chunk);
            self.word(u64::from_le_bytes(w));
        }
        self
    }

    /// Adds another key's two lanes.
    pub(crate) fn key_words(&mut self, k: &StartKey) -> &mut Self {
        self.word(k.0[0]);
        self.word(k.0[1]);
        self
    }

    /// The key: each lane finished by SplitMix64's mixer with the count of words.
    pub(crate) fn key(&self) -> StartKey {
        let mix = |mut z: u64| {
            z = (z ^ (z >> 30)).wrapping_mul(0xBF58_476D_1CE4_E5B9);
            z = (z ^ (z >> 27)).wrapping_mul(0x94D0_49BB_1331_11EB);
            z ^ (z >> 31)
        };
        StartKey([mix(self.a ^ self.n), mix(self.b.wrapping_add(self.n))])
    }
}

/// A fitted start state, or the error the fit ended with.
pub(crate) type Start = Result<(Vec<f64>, Vec<f64>)>;

/// A run's R-MSE on its record per DOF, or the error the run (or the score) ended with.
pub(crate) type Scores = Result<Vec<f64>>;

/// One kind of entry, the oldest forgotten past [`CAPACITY`].
struct Memo<T> {
    map: HashMap<StartKey, T>,
    order: VecDeque<StartKey>,
}

impl<T: Clone> Memo<T> {
    fn new() -> Self {
        Self {
            map: HashMap::new(),
            order: VecDeque::new(),
        }
    }

    fn put(&mut self, key: StartKey, value: &T) {
        if self.map.insert(key, value.clone()).is_none() {
            self.order.push_back(key);
        }
        while self.order.len() > CAPACITY {
            if let Some(old) = self.order.pop_front() {
                self.map.remove(&old);
            }
        }
    }
}

fn starts() -> &'static Mutex<Memo<Start>> {
    static MEMO: OnceLock<Mutex<Memo<Start>>> = OnceLock::new();
    MEMO.get_or_init(|| Mutex::new(Memo::new()))
}

fn scores() -> &'static Mutex<Memo<Scores>> {
    static MEMO: OnceLock<Mutex<Memo<Scores>>> = OnceLock::new();
    MEMO.get_or_init(|| Mutex::new(Memo::new()))
}

/// The start kept under `key`, if any.
pub(crate) fn get(key: &StartKey) -> Option<Start> {
    starts().lock().ok()?.map.get(key).cloned()
}

/// Keeps `start` under `key`, forgetting the oldest entry when the memo is full.
pub(crate) fn put(key: StartKey, start: &Start) {
    if let Ok(mut m) = starts().lock() {
        m.put(key, start);
    }
}

/// The scores of the run kept under `key`, if any.
pub(crate) fn get_scores(key: &StartKey) -> Option<Scores> {
    scores().lock().ok()?.map.get(key).cloned()
}

/// Keeps a run's `scores` under `key`, forgetting the oldest entry when the memo is full.
pub(crate) fn put_scores(key: StartKey, value: &Scores) {
    if let Ok(mut m) = scores().lock() {
        m.put(key, value);
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// One value's last bit, a value moved between slices, or a longer slice each change the
    /// key; the same inputs give the same key.
    #[test]
    fn keys_follow_every_bit_and_the_split() {
        let key = |parts: &[&[f64]], s: &str| {
            let mut h = KeyHasher::new();
            for p in parts {
                h.floats(p);
            }
            h.text(s).key()
        };
        let base = key(&[&[1.0, 2.0], &[3.0]], "m");
        assert_eq!(base, key(&[&[1.0, 2.0], &[3.0]], "m"));
        let nudged = f64::from_bits(2.0f64.to_bits() + 1);
        assert_ne!(base, key(&[&[1.0, nudged], &[3.0]], "m"));
        assert_ne!(base, key(&[&[1.0], &[2.0, 3.0]], "m"));
        assert_ne!(base, key(&[&[1.0, 2.0], &[3.0, 0.0]], "m"));
        assert_ne!(base, key(&[&[1.0, 2.0], &[3.0]], "n"));
        assert_ne!(key(&[], "ab"), key(&[], "ab\0"));
    }
}
