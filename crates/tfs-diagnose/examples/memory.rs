//! Peak heap of `tfs_diagnose::diagnose` per record sample, to keep its memory within a few
//! times the records as they grow: one Duffing sweep with hidden dry friction at 40 dB, sampled
//! at 100 Hz, the start model fitted without the friction (so the scan, the judge and the
//! calibrated null all run), for each record length given in seconds.
//! Usage: `cargo run -p tfs-diagnose --example memory -- [SECONDS ...]` (default 100 400 1600).
//! A counting allocator measures the live heap; the figure printed is the peak during the
//! call above what was live before it (the records and the model), in bytes per sample and as a
//! multiple of the record's `t, x, xb_acc` columns (24 bytes per sample).

#[path = "../tests/common/mod.rs"]
mod common;

use std::alloc::{GlobalAlloc, Layout, System};
use std::sync::atomic::{AtomicUsize, Ordering};

use common::*;
use tfs_diagnose::{DiagnoseOptions, diagnose, refit};

/// The system allocator, counting the bytes live and their peak.
struct Counting;

static LIVE: AtomicUsize = AtomicUsize::new(0);
static PEAK: AtomicUsize = AtomicUsize::new(0);

fn grew(by: usize) {
    let now = LIVE.fetch_add(by, Ordering::Relaxed) + by;
    PEAK.fetch_max(now, Ordering::Relaxed);
}

// SAFETY: every call is forwarded to `System` unchanged; only counters are updated beside it.
unsafe impl GlobalAlloc for Counting {
    unsafe fn alloc(&self, layout: Layout) -> *mut u8 {
        let p = unsafe { System.alloc(layout) };
        if !p.is_null() {
            grew(layout.size());
        }
        p
    }
    unsafe fn alloc_zeroed(&self, layout: Layout) -> *mut u8 {
        let p = unsafe { System.alloc_zeroed(layout) };
        if !p.is_null() {
            grew(layout.size());
        }
        p
    }
    unsafe fn dealloc(&self, ptr: *mut u8, layout: Layout) {
        unsafe { System.dealloc(ptr, layout) };
        LIVE.fetch_sub(layout.size(), Ordering::Relaxed);
    }
    unsafe fn realloc(&self, ptr: *mut u8, layout: Layout, new_size: usize) -> *mut u8 {
        let p = unsafe { System.realloc(ptr, layout, new_size) };
        if !p.is_null() {
            LIVE.fetch_sub(layout.size(), Ordering::Relaxed);
            grew(new_size);
        }
        p
    }
}

#[global_allocator]
static ALLOCATOR: Counting = Counting;

fn main() -> Result<(), Box<dyn std::error::Error>> {
    let mut lengths: Vec<f64> = std::env::args()
        .skip(1)
        .map(|a| a.parse())
        .collect::<Result<_, _>>()?;
    if lengths.is_empty() {
        lengths = vec![100.0, 400.0, 1600.0];
    }
    let truth = Truth {
        restoring: duffing_restoring(),
        damping: 0.63,
        hidden: vec![Hidden::DryFriction {
            force: 2.0,
            eps: 0.02,
        }],
        x0: 0.0,
    };
    println!("seconds  samples  peak MB  bytes/sample  x record  effect named");
    for secs in lengths {
        let r = record(&truth, "sweep", 0.3, 3.0, 4.0, secs, 0.01, 10);
        let records = vec![r];
        let opts = DiagnoseOptions::default();
        let start = refit(&structure("x, x^3, x', xb_acc"), &records, &opts)?;
        let before = LIVE.load(Ordering::Relaxed);
        PEAK.store(before, Ordering::Relaxed);
        let d = diagnose(&start, &records, &opts)?;
        let peak = PEAK.load(Ordering::Relaxed) - before;
        let n = records[0].len();
        let named = d
            .ranked
            .iter()
            .find(|e| e.significant)
            .map_or("none", |e| e.effect.as_str());
        println!(
            "{secs:7.0}  {n:7}  {:7.1}  {:12.0}  {:8.1}  {named}",
            peak as f64 / 1e6,
            peak as f64 / n as f64,
            peak as f64 / (24.0 * n as f64)
        );
    }
    Ok(())
}
