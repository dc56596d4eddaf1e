//! Coarse-to-fine labelling of a grid: integrate a coarse lattice of starts, then at each finer
//! level integrate only the new starts whose surroundings are not uniform, and give the others
//! the label their surroundings share.
//!
//! "Uniform" is strict: every coarse node in the 4 × 4 block around the new node (the coarse
//! cell holding it and one coarse cell on every side) has the same stable state *and* reached it
//! after the same number of region changes (`Outcome::turns`: crossings between wells). Two
//! neighbouring starts that end in the same state by different routes (one crossing the saddle
//! twice more than the other) have a band of the other basin between them even when the coarse
//! lattice steps over it, so such blocks are refined too. Unsettled and diverged starts are
//! never copied.

use crate::grid::Label;
use crate::lanes::Outcome;

/// Coarsest lattice step (in grid cells) for large grids.
pub(crate) const COARSEST: usize = 8;
/// Coarse cells on every side of a new node that must agree before it is filled.
const DILATION: usize = 1;

/// The lattice step to start from on an `nx × ny` grid: [`COARSEST`], halved until the coarse
/// lattice has at least 16 intervals along the shorter axis (1 = integrate every node).
pub(crate) fn coarse_step(nx: usize, ny: usize) -> usize {
    let mut s = COARSEST;
    while s > 1 && (nx.min(ny) - 1) / s < 16 {
        s /= 2;
    }
    s
}

/// Node indices along an axis of `n` nodes on the lattice of step `s`: the multiples of `s` and
/// the last node.
fn axis(n: usize, s: usize) -> Vec<usize> {
    let mut a: Vec<usize> = (0..n).step_by(s).collect();
    if a.last() != Some(&(n - 1)) {
        a.push(n - 1);
    }
    a
}

/// Positions in `coarse` of the nodes around `i` (the enclosing interval widened by
/// [`DILATION`] on both sides, clamped to the axis).
fn around(coarse: &[usize], i: usize) -> std::ops::RangeInclusive<usize> {
    let (lo, hi) = match coarse.binary_search(&i) {
        Ok(a) => (a, a),
        Err(b) => (b - 1, b),
    };
    lo.saturating_sub(DILATION)..=(hi + DILATION).min(coarse.len() - 1)
}

/// Statistics of a coarse-to-fine run.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub(crate) struct Work {
    /// Starts integrated.
    pub(crate) integrated: usize,
    /// Starts labelled from their surroundings.
    pub(crate) filled: usize,
}

/// Labels every node of an `nx × ny` grid (row-major, `j * nx + i`) starting from lattice step
/// `step`; `compute(cells)` integrates the listed nodes and returns their outcomes in order.
/// `resolved(n)` is told how many nodes have a label so far. Deterministic: what is integrated
/// depends only on the outcomes, never on timing.
pub(crate) fn coarse_to_fine(
    nx: usize,
    ny: usize,
    step: usize,
    compute: &mut dyn FnMut(&[usize]) -> Vec<Outcome>,
    resolved: &dyn Fn(usize),
) -> (Vec<Label>, Work) {
    let mut known: Vec<Option<Outcome>> = vec![None; nx * ny];
    let mut work = Work::default();
    let mut s = step.max(1);
    let first: Vec<usize> = {
        let (xs, ys) = (axis(nx, s), axis(ny, s));
        ys.iter()
            .flat_map(|&j| xs.iter().map(move |&i| j * nx + i))
            .collect()
    };
    for (&c, o) in first.iter().zip(compute(&first)) {
        known[c] = Some(o);
    }
    work.integrated += first.len();
    resolved(work.integrated);
    while s > 1 {
        let h = s / 2;
        let (cx, cy) = (axis(nx, s), axis(ny, s));
        let (fx, fy) = (axis(nx, h), axis(ny, h));
        let mut todo = Vec::new();
        let mut fill = Vec::new();
        for &j in &fy {
            let on_row = cy.binary_search(&j).is_ok();
            let rows = around(&cy, j);
            for &i in &fx {
                if on_row && cx.binary_search(&i).is_ok() {
                    continue; // already on the coarser lattice
                }
                let cols = around(&cx, i);
                let mut common: Option<Outcome> = None;
                let mut uniform = true;
                'scan: for b in rows.clone() {
                    for a in cols.clone() {
                        let o = known[cy[b] * nx + cx[a]].expect("coarser lattice is labelled");
                        let same = matches!(o.label, Label::State(_))
                            && common.is_none_or(|c: Outcome| c == o);
                        if !same {
                            uniform = false;
                            break 'scan;
                        }
                        common = Some(o);
                    }
                }
                let c = j * nx + i;
                match (uniform, common) {
                    (true, Some(o)) => fill.push((c, o)),
                    _ => todo.push(c),
                }
            }
        }
        for (&c, o) in todo.iter().zip(compute(&todo)) {
            known[c] = Some(o);
        }
        for &(c, o) in &fill {
            known[c] = Some(o);
        }
        work.integrated += todo.len();
        work.filled += fill.len();
        resolved(work.integrated + work.filled);
        s = h;
    }
    let labels = known
        .into_iter()
        .map(|o| o.expect("every node is labelled at step 1").label)
        .collect();
    (labels, work)
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A synthetic map: the label of a node is a function of its position, and `turns` counts
    /// the bands crossed, as an integrated start would report.
    fn bands(nx: usize, ny: usize, f: impl Fn(usize, usize) -> (usize, u32)) -> Vec<Outcome> {
        (0..nx * ny)
            .map(|c| {
                let (k, t) = f(c % nx, c / nx);
                Outcome {
                    label: Label::State(k),
                    turns: t,
                }
            })
            .collect()
    }

    fn run(nx: usize, ny: usize, truth: &[Outcome], step: usize) -> (Vec<Label>, Work) {
        let mut compute = |cells: &[usize]| cells.iter().map(|&c| truth[c]).collect();
        coarse_to_fine(nx, ny, step, &mut compute, &|_| {})
    }

    #[test]
    fn axis_holds_multiples_and_the_last_node() {
        assert_eq!(axis(10, 4), vec![0, 4, 8, 9]);
        assert_eq!(axis(9, 4), vec![0, 4, 8]);
        assert_eq!(axis(5, 1), vec![0, 1, 2, 3, 4]);
        assert_eq!(coarse_step(1000, 1000), 8);
        assert_eq!(coarse_step(100, 60), 2);
        assert_eq!(coarse_step(20, 20), 1);
    }

    #[test]
    fn straight_boundaries_are_exact_and_save_work() {
        let (nx, ny) = (257, 131);
        // Three diagonal bands: labels 0, 1, 0 with turns 0, 1, 2.
        let truth = bands(nx, ny, |i, j| {
            let b = ((i + 2 * j) / 120).min(2);
            ((b % 2), b as u32)
        });
        let (labels, work) = run(nx, ny, &truth, 8);
        let want: Vec<Label> = truth.iter().map(|o| o.label).collect();
        assert_eq!(labels, want);
        assert_eq!(work.integrated + work.filled, nx * ny);
        assert!(work.integrated < nx * ny / 3, "{work:?}");
    }

    #[test]
    fn a_band_thinner_than_the_coarse_step_is_found_by_its_turns() {
        let (nx, ny) = (129, 129);
        // A 3-node-wide band of state 1 along a column the coarse lattice steps over; the
        // nodes beyond it end in state 0 after two turns instead of none.
        let truth = bands(nx, ny, |i, _| match i {
            0..=68 => (0, 0),
            69..=71 => (1, 1),
            _ => (0, 2),
        });
        let (labels, _) = run(nx, ny, &truth, 8);
        let want: Vec<Label> = truth.iter().map(|o| o.label).collect();
        assert_eq!(labels, want);
        // Without the turns the band would have been filled over.
        let blind: Vec<Outcome> = truth.iter().map(|o| Outcome { turns: 0, ..*o }).collect();
        let (labels, _) = run(nx, ny, &blind, 8);
        assert_ne!(labels, want);
    }

    #[test]
    fn unsettled_nodes_are_never_copied() {
        let (nx, ny) = (65, 65);
        // A block of unsettled starts inside one basin: every node near it is integrated, so
        // the block comes out exactly and nothing outside it is called unsettled.
        let mut truth = bands(nx, ny, |_, _| (0, 0));
        for j in 20..31 {
            for i in 33..45 {
                truth[j * nx + i].label = Label::Unsettled;
            }
        }
        let (labels, work) = run(nx, ny, &truth, 4);
        let want: Vec<Label> = truth.iter().map(|o| o.label).collect();
        assert_eq!(labels, want);
        assert!(work.filled > 0);
    }
}
