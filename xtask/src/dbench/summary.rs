//! Scoring a benchmark run like a classifier: confusion matrix (hidden × top-ranked), top-1
//! accuracy, false alarms on controls, held-out error drops, detection thresholds in effect size
//! and time per case; as Markdown, JSON and figures.

use super::case::{Answer, CaseResult, Group};
use super::truth::Kind;
use crate::common::{f4, pct};

/// The diagnosis's own minimum effect size (share of the force RMS) by default.
pub const MIN_SHARE: f64 = 0.02;

/// Bins of an effect's size measure in the report: below the diagnosis's minimum size, then
/// small, medium and large.
pub const BINS: [(f64, f64); 4] = [
    (0.0, MIN_SHARE),
    (MIN_SHARE, 0.05),
    (0.05, 0.15),
    (0.15, f64::INFINITY),
];

/// Which size of a hidden effect a score is binned or thresholded by.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Measure {
    /// The RMS of its force over the RMS acceleration.
    Realised,
    /// The RMS of the part of its force the start library cannot hold, over the RMS
    /// acceleration.
    Unrepresentable,
}

impl Measure {
    /// The first hidden effect's size of case `c` by this measure.
    pub fn of(self, c: &CaseResult) -> Option<f64> {
        match self {
            Measure::Realised => c.realised.first().copied(),
            Measure::Unrepresentable => c.unrepresentable.first().copied(),
        }
        .filter(|v| v.is_finite())
    }
}

/// The detection floor at SNR `snr` (dB; None: noise-free): the larger of the diagnosis's
/// minimum size and the records' relative noise amplitude `10^(−snr/20)` (the noise RMS over
/// the signal RMS on each measured channel). An effect whose unrepresentable part is below it
/// leaves too little for any model from the start library to miss: finding nothing is then an
/// acceptable answer.
pub fn floor(snr: Option<f64>) -> f64 {
    snr.map_or(MIN_SHARE, |s| MIN_SHARE.max(10f64.powf(-s / 20.0)))
}

/// Whether case `c`'s (first) hidden effect leaves an unrepresentable part at or above the
/// detection floor of its noise level; cases without the measure count as detectable.
pub fn detectable(c: &CaseResult) -> bool {
    Measure::Unrepresentable
        .of(c)
        .is_none_or(|u| u >= floor(c.spec.snr))
}

/// Scores of the single-effect cases whose size lies in one bin.
#[derive(Debug, Clone, Copy)]
pub struct Binned {
    /// Named first.
    pub correct: usize,
    /// Cases.
    pub n: usize,
    /// Median held-out error factor after round 1.
    pub drop: f64,
}

/// The "nothing detectable" reading of a noise group's single-effect cases.
#[derive(Debug, Clone, Copy)]
pub struct Detectable {
    /// Detectable cases named first.
    pub correct: usize,
    /// Detectable cases.
    pub n: usize,
    /// Undetectable cases answered acceptably (nothing named, or the hidden effect itself).
    pub quiet: usize,
    /// Undetectable cases.
    pub n_quiet: usize,
}

/// Round 1's answers of a noise group's counted single-effect cases, by what the held-out
/// record says of the hidden effect added by name ([`Answer`]).
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq)]
pub struct Answers {
    /// Counted cases.
    pub n: usize,
    /// Found first.
    pub found: usize,
    /// Missed; the hidden effect predicts the held-out record better than the answer.
    pub hidden_better: usize,
    /// Missed; the hidden effect predicts it no better than the answer.
    pub not_better: usize,
    /// Missed; the hidden effect's refit does not simulate it.
    pub hidden_fails: usize,
}

/// Noise groups of the report.
pub const GROUPS: [(&str, &[Option<f64>]); 3] = [
    ("≥40 dB", &[None, Some(40.0)]),
    ("30 dB", &[Some(30.0)]),
    ("20 dB", &[Some(20.0)]),
];

fn in_group(c: &CaseResult, g: &[Option<f64>]) -> bool {
    g.contains(&c.spec.snr)
}

/// Median of finite values (NaN when none).
pub fn median(mut v: Vec<f64>) -> f64 {
    v.retain(|x| x.is_finite());
    if v.is_empty() {
        return f64::NAN;
    }
    v.sort_by(f64::total_cmp);
    let n = v.len();
    if n % 2 == 1 {
        v[n / 2]
    } else {
        0.5 * (v[n / 2 - 1] + v[n / 2])
    }
}

/// `a` of `n` as a percentage with the counts, or a dash when `n` is 0.
pub fn cell(a: usize, n: usize) -> String {
    if n == 0 {
        "—".into()
    } else {
        format!("{} ({a}/{n})", pct(a as f64 / n as f64))
    }
}

/// Where detection stops for one effect at one noise group, from its cases sorted by size.
#[derive(Debug, Clone, Copy)]
pub struct Threshold {
    /// Cases.
    pub n: usize,
    /// Smallest realised size found first.
    pub smallest_found: f64,
    /// Smallest size above which at least 90 % of the cases are found first (NaN: never).
    pub s90: f64,
    /// Largest size not found first (NaN: none missed).
    pub largest_missed: f64,
}

/// Where detection of one effect stops at one noise group: the split of its cases, sorted by a
/// size measure, that best separates those missed (below) from those found first (above).
#[derive(Debug, Clone, Copy)]
pub struct Limit {
    /// The size of the smallest case above the split (NaN: the best split leaves every case
    /// below, nothing is found).
    pub at: f64,
    /// Largest size below the split (NaN: none below).
    pub below_max: f64,
    /// (found first, cases) above the split.
    pub above: (usize, usize),
    /// (found first, cases) below the split.
    pub below: (usize, usize),
}

impl Limit {
    /// The split of `v` (size, found first) with the fewest cases on the wrong side (found
    /// below, missed above); among equally good splits the highest (the limit is not put lower
    /// than the cases support).
    pub fn of(mut v: Vec<(f64, bool)>) -> Self {
        v.sort_by(|a, b| a.0.total_cmp(&b.0));
        let n = v.len();
        let total_found = v.iter().filter(|x| x.1).count();
        // found_below[k]: found among cases [0, k) (below a split before case k).
        let found_below: Vec<usize> = std::iter::once(0)
            .chain(v.iter().scan(0, |acc, x| {
                *acc += x.1 as usize;
                Some(*acc)
            }))
            .collect();
        let (mut best, mut best_k) = (usize::MAX, n);
        for (k, &fb) in found_below.iter().enumerate() {
            let missed_above = (n - k) - (total_found - fb);
            if fb + missed_above <= best {
                best = fb + missed_above;
                best_k = k;
            }
        }
        let fb = found_below[best_k];
        Limit {
            at: v.get(best_k).map_or(f64::NAN, |x| x.0),
            below_max: if best_k > 0 {
                v[best_k - 1].0
            } else {
                f64::NAN
            },
            above: (total_found - fb, n - best_k),
            below: (fb, best_k),
        }
    }
}

/// The scored run.
pub struct Summary<'a> {
    cases: &'a [CaseResult],
    catalogue: &'a [String],
}

impl<'a> Summary<'a> {
    /// Scores `cases` of a run over `catalogue`.
    pub fn new(cases: &'a [CaseResult], catalogue: &'a [String]) -> Self {
        Self { cases, catalogue }
    }

    /// Every case of the run.
    pub fn cases(&self) -> &[CaseResult] {
        self.cases
    }

    /// The catalogue's effect names.
    pub fn catalogue(&self) -> &[String] {
        self.catalogue
    }

    /// (size by `measure`, found first) of every single-effect case of noise group `g`.
    pub fn single_sized(&self, g: &[Option<f64>], measure: Measure) -> Vec<(f64, bool)> {
        self.of(Group::Single, g)
            .filter_map(|c| Some((measure.of(c)?, c.top1_correct())))
            .collect()
    }

    fn of(&self, group: Group, g: &[Option<f64>]) -> impl Iterator<Item = &CaseResult> + '_ {
        let g = g.to_vec();
        self.cases
            .iter()
            .filter(move |c| c.ok() && c.spec.group == group && in_group(c, &g))
    }

    /// Single-effect cases counted for accuracy: the effect's realised size at least the
    /// diagnosis's own minimum size (smaller ones are reported apart).
    fn counted(&self, g: &[Option<f64>]) -> Vec<&CaseResult> {
        self.of(Group::Single, g)
            .filter(|c| {
                c.realised
                    .first()
                    .is_none_or(|s| s.partial_cmp(&MIN_SHARE) != Some(std::cmp::Ordering::Less))
            })
            .collect()
    }

    /// (correct, total) top-1 over counted single cases of noise group `g`, optionally one
    /// effect and one baseline.
    pub fn top1(
        &self,
        g: &[Option<f64>],
        effect: Option<&str>,
        kind: Option<Kind>,
    ) -> (usize, usize) {
        let v: Vec<_> = self
            .counted(g)
            .into_iter()
            .filter(|c| effect.is_none_or(|e| c.spec.hidden[0] == e))
            .filter(|c| kind.is_none_or(|k| c.spec.kind == k))
            .collect();
        (v.iter().filter(|c| c.top1_correct()).count(), v.len())
    }

    /// (named first or tied with the first, total) over counted single cases of noise group `g`.
    pub fn top1_or_tied(&self, g: &[Option<f64>]) -> (usize, usize) {
        let v = self.counted(g);
        (v.iter().filter(|c| c.top1_or_tied()).count(), v.len())
    }

    /// Round 1's answers over the counted single cases of noise group `g` (only those whose
    /// unrepresentable part reaches the detection floor when `detectable_only`), by what the
    /// held-out record says of the hidden effect added by name. `found + hidden_better` is the
    /// top-1 a ranking would reach that missed only where the held-out record gives no reason
    /// to prefer the hidden effect.
    pub fn answers(&self, g: &[Option<f64>], detectable_only: bool) -> Answers {
        let mut a = Answers::default();
        for c in self
            .counted(g)
            .into_iter()
            .filter(|c| !detectable_only || detectable(c))
        {
            a.n += 1;
            match c.answer() {
                Answer::Found => a.found += 1,
                Answer::HiddenBetter => a.hidden_better += 1,
                Answer::NotBetter => a.not_better += 1,
                Answer::HiddenFails => a.hidden_fails += 1,
            }
        }
        a
    }

    /// (alarms, controls) of noise group `g`, optionally one baseline.
    pub fn false_alarms(&self, g: &[Option<f64>], kind: Option<Kind>) -> (usize, usize) {
        let v: Vec<_> = self
            .of(Group::Control, g)
            .filter(|c| kind.is_none_or(|k| c.spec.kind == k))
            .collect();
        (v.iter().filter(|c| c.found(0) != "none").count(), v.len())
    }

    /// Median held-out error factor after round 1 over counted single cases (nothing added
    /// counts as 1×; a failed simulation after adding is excluded and counted).
    pub fn drop(&self, g: &[Option<f64>], effect: Option<&str>) -> (f64, usize) {
        let v: Vec<_> = self
            .counted(g)
            .into_iter()
            .filter(|c| effect.is_none_or(|e| c.spec.hidden[0] == e))
            .collect();
        let failed = v.iter().filter(|c| c.drop(0).is_none()).count();
        (median(v.iter().filter_map(|c| c.drop(0)).collect()), failed)
    }

    /// Median held-out factor when the hidden effect itself is added by name.
    pub fn oracle_drop(&self, g: &[Option<f64>], effect: &str) -> f64 {
        median(
            self.counted(g)
                .into_iter()
                .filter(|c| c.spec.hidden[0] == effect)
                .filter_map(|c| Some(c.rounds.first()?.before? / c.oracle_after?))
                .collect(),
        )
    }

    /// Pairs of group `g`: (both found in two rounds, total, median factor after two rounds).
    pub fn pairs(&self, g: &[Option<f64>]) -> (usize, usize, f64) {
        let v: Vec<_> = self.of(Group::Pair, g).collect();
        let both = v
            .iter()
            .filter(|c| {
                let (a, b) = (c.named_hidden(0), c.named_hidden(1));
                matches!((a, b), (Some(x), Some(y)) if x != y)
            })
            .count();
        let drops = v
            .iter()
            .filter_map(|c| {
                let before = c.rounds.first()?.before?;
                let after = c.rounds.last()?.after?;
                Some(before / after)
            })
            .collect();
        (both, v.len(), median(drops))
    }

    /// Where detection of `effect` stops at noise levels `g`, by realised size, 90 % found.
    pub fn threshold(&self, g: &[Option<f64>], effect: &str) -> Threshold {
        self.threshold_by(g, effect, Measure::Realised, 0.9)
    }

    /// Where detection of `effect` stops at noise levels `g`, by `measure`: the smallest size
    /// above which at least the fraction `frac` of the cases are found first.
    pub fn threshold_by(
        &self,
        g: &[Option<f64>],
        effect: &str,
        measure: Measure,
        frac: f64,
    ) -> Threshold {
        let mut v: Vec<(f64, bool)> = self
            .of(Group::Single, g)
            .filter(|c| c.spec.hidden[0] == effect)
            .filter_map(|c| Some((measure.of(c)?, c.top1_correct())))
            .collect();
        v.sort_by(|a, b| a.0.total_cmp(&b.0));
        let smallest_found = v.iter().find(|x| x.1).map_or(f64::NAN, |x| x.0);
        let largest_missed = v.iter().rev().find(|x| !x.1).map_or(f64::NAN, |x| x.0);
        // From the top down: the last size at which the cases from there up are ≥ 90 % found.
        let mut s90 = f64::NAN;
        let (mut found, mut seen) = (0usize, 0usize);
        for &(s, ok) in v.iter().rev() {
            seen += 1;
            found += ok as usize;
            if found as f64 >= frac * seen as f64 {
                s90 = s;
            }
        }
        Threshold {
            n: v.len(),
            smallest_found,
            s90,
            largest_missed,
        }
    }

    /// Where detection of `effect` stops at noise levels `g`, by `measure` ([`Limit::of`]).
    pub fn limit(&self, g: &[Option<f64>], effect: &str, measure: Measure) -> Limit {
        Limit::of(
            self.of(Group::Single, g)
                .filter(|c| c.spec.hidden[0] == effect)
                .filter_map(|c| Some((measure.of(c)?, c.top1_correct())))
                .collect(),
        )
    }

    /// Top-1 and median drop over the single-effect cases of noise group `g` whose `measure`
    /// lies in `[lo, hi)` (every size, not only the counted ones: the bins show the small ones).
    pub fn binned(&self, g: &[Option<f64>], measure: Measure, (lo, hi): (f64, f64)) -> Binned {
        let v: Vec<&CaseResult> = self
            .of(Group::Single, g)
            .filter(|c| measure.of(c).is_some_and(|s| s >= lo && s < hi))
            .collect();
        Binned {
            correct: v.iter().filter(|c| c.top1_correct()).count(),
            n: v.len(),
            drop: median(v.iter().filter_map(|c| c.drop(0)).collect()),
        }
    }

    /// The "nothing detectable" reading of noise group `g`: over every single-effect case,
    /// those whose unrepresentable part reaches the detection floor ([`floor`]) are scored by
    /// top-1; the others are answered acceptably by naming nothing (or the hidden effect).
    pub fn detectable(&self, g: &[Option<f64>]) -> Detectable {
        let (yes, no): (Vec<&CaseResult>, Vec<&CaseResult>) =
            self.of(Group::Single, g).partition(|c| detectable(c));
        Detectable {
            correct: yes.iter().filter(|c| c.top1_correct()).count(),
            n: yes.len(),
            quiet: no
                .iter()
                .filter(|c| c.found(0) == "none" || c.top1_correct())
                .count(),
            n_quiet: no.len(),
        }
    }

    /// Median held-out drop over the detectable single-effect cases of group `g`.
    pub fn detectable_drop(&self, g: &[Option<f64>]) -> f64 {
        median(
            self.of(Group::Single, g)
                .filter(|c| detectable(c))
                .filter_map(|c| c.drop(0))
                .collect(),
        )
    }

    /// Confusion counts of group `g`: rows are hidden effects (and "control"), columns what
    /// round 1 named (and "none").
    pub fn confusion(&self, g: &[Option<f64>]) -> (Vec<String>, Vec<String>, Vec<Vec<usize>>) {
        let mut rows: Vec<String> = self.catalogue.to_vec();
        rows.push("control".into());
        let mut cols: Vec<String> = self.catalogue.to_vec();
        cols.push("none".into());
        let mut m = vec![vec![0usize; cols.len()]; rows.len()];
        for c in self.cases.iter().filter(|c| c.ok() && in_group(c, g)) {
            let r = match c.spec.group {
                Group::Single => c.spec.hidden[0].clone(),
                Group::Control => "control".into(),
                Group::Pair => continue,
            };
            let found = c.found(0);
            let (Some(i), Some(j)) = (
                rows.iter().position(|x| *x == r),
                cols.iter().position(|x| *x == found),
            ) else {
                continue;
            };
            m[i][j] += 1;
        }
        (rows, cols, m)
    }

    /// Seconds per case: (median, max), over cases that ran.
    pub fn times(&self, kind: Option<Kind>) -> (f64, f64) {
        let t: Vec<f64> = self
            .cases
            .iter()
            .filter(|c| c.ok() && kind.is_none_or(|k| c.spec.kind == k))
            .map(|c| c.seconds)
            .collect();
        let max = t.iter().copied().fold(f64::NAN, f64::max);
        (median(t), max)
    }

    /// The three done-criteria numbers in one paragraph.
    pub fn headline(&self) -> String {
        let g = GROUPS[0].1;
        let (c, n) = self.top1(g, None, None);
        let (fa, nc) = self.false_alarms(g, None);
        let (d, _) = self.drop(g, None);
        format!(
            "at 40 dB and above: top-1 correct {}; false alarms on controls {}; median held-out error drop after the top effect {}×",
            cell(c, n),
            cell(fa, nc),
            f4(d)
        )
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::dbench::case::{CaseSpec, Round};

    /// A case that ran: `hidden` at `snr` with realised size `size`, round 1 named `named`
    /// (`None`: nothing significant) and moved the held-out error from `before` to `after`.
    fn case(
        group: Group,
        hidden: &[&str],
        snr: Option<f64>,
        size: f64,
        named: Option<&str>,
        before: f64,
        after: f64,
    ) -> CaseResult {
        let spec = CaseSpec {
            id: 0,
            kind: Kind::Duffing,
            group,
            hidden: hidden.iter().map(|s| s.to_string()).collect(),
            sizes: vec![size; hidden.len()],
            snr,
            seed: 0,
        };
        let mut c = CaseResult::new(&spec);
        c.realised = vec![size; hidden.len()];
        c.unrepresentable = vec![size; hidden.len()];
        c.hidden_dofs = vec![vec!["x1".to_string()]; hidden.len()];
        c.rounds.push(Round {
            top: named.map(String::from),
            top_effect: named.map(|n| n.split('@').next().unwrap_or(n).to_string()),
            top_parameter: None,
            verdict: String::new(),
            simulation: None,
            ranked: Vec::new(),
            tied: Vec::new(),
            before: Some(before),
            after: Some(after),
            free_run: (Some(before), Some(after)),
            failure: None,
            seconds: 1.0,
        });
        c
    }

    /// Each miss is sorted by the hidden effect's own held-out score against the answer's: a
    /// failed answer counts as beaten, a failed oracle apart, an equal score as not better;
    /// cases below the detection floor leave the detectable count only.
    #[test]
    fn sorts_misses_by_what_the_held_out_record_says() {
        let s40 = Some(40.0);
        let with_oracle = |mut c: CaseResult, o: Option<f64>| {
            c.oracle_after = o;
            c
        };
        let mut failed_answer = case(Group::Single, &["a"], s40, 0.3, Some("b"), 1.0, 1.0);
        failed_answer.rounds[0].after = None;
        let cases = vec![
            with_oracle(
                case(Group::Single, &["a"], s40, 0.3, Some("a"), 1.0, 0.1),
                None,
            ),
            with_oracle(
                case(Group::Single, &["a"], s40, 0.3, Some("b"), 1.0, 0.5),
                Some(0.2),
            ),
            with_oracle(
                case(Group::Single, &["a"], s40, 0.3, Some("b"), 1.0, 0.5),
                Some(0.5),
            ),
            with_oracle(
                case(Group::Single, &["a"], s40, 0.3, None, 1.0, 1.0),
                Some(3.0),
            ),
            with_oracle(case(Group::Single, &["a"], s40, 0.3, None, 1.0, 1.0), None),
            with_oracle(failed_answer, Some(2.0)),
            // Realised 3 %, but the start library holds all but 0.5 % of it: counted, not
            // detectable.
            {
                let mut c = case(Group::Single, &["b"], None, 0.03, None, 1.0, 1.0);
                c.unrepresentable = vec![0.005];
                with_oracle(c, Some(0.1))
            },
        ];
        let cat: Vec<String> = ["a", "b"].map(String::from).to_vec();
        let s = Summary::new(&cases, &cat);
        let g = GROUPS[0].1;
        let all = s.answers(g, false);
        assert_eq!(
            all,
            Answers {
                n: 7,
                found: 1,
                hidden_better: 3,
                not_better: 2,
                hidden_fails: 1
            }
        );
        assert_eq!(all.found, s.top1(g, None, None).0);
        let det = s.answers(g, true);
        assert_eq!((det.n, det.hidden_better), (6, 2));
        assert_eq!(s.answers(GROUPS[2].1, false), Answers::default());
    }

    /// A hand-built run whose every score is known: the scoring must reproduce it.
    #[test]
    fn scores_a_hand_built_confusion() {
        let cat: Vec<String> = ["a", "b", "c"].map(String::from).to_vec();
        let s40 = Some(40.0);
        let mut cases = vec![
            case(Group::Single, &["a"], s40, 0.3, Some("a"), 1.0, 0.1), // right, 10x
            case(Group::Single, &["a"], None, 0.3, Some("b"), 1.0, 0.5), // wrong, 2x
            case(Group::Single, &["b"], s40, 0.3, Some("b"), 1.0, 0.2), // right, 5x
            case(Group::Single, &["c"], s40, 0.3, None, 1.0, 1.0),      // missed, 1x
            // On the wrong DOF of a chain: wrong, 1.25x.
            case(Group::Single, &["c"], s40, 0.3, Some("c@x2"), 1.0, 0.8),
            // Below the minimum size: in the matrix, not in top-1 or the drop.
            case(Group::Single, &["c"], s40, 0.005, Some("c"), 1.0, 0.01),
            case(Group::Control, &[], s40, 0.0, None, 1.0, 1.0),
            case(Group::Control, &[], None, 0.0, Some("a"), 1.0, 0.9), // false alarm
            case(Group::Control, &[], s40, 0.0, None, 1.0, 1.0),
            case(Group::Control, &[], s40, 0.0, None, 1.0, 1.0),
            // Other noise group: not in the ≥40 dB scores.
            case(Group::Single, &["a"], Some(20.0), 0.3, Some("b"), 1.0, 1.0),
            case(Group::Control, &[], Some(20.0), 0.0, Some("b"), 1.0, 1.0),
        ];
        // A case that failed counts nowhere.
        let mut failed = case(Group::Single, &["a"], s40, 0.3, Some("a"), 1.0, 0.1);
        failed.status = "failed".into();
        cases.push(failed);
        let s = Summary::new(&cases, &cat);
        let g = GROUPS[0].1;

        assert_eq!(s.top1(g, None, None), (2, 5));
        assert_eq!(s.top1(g, Some("a"), None), (1, 2));
        assert_eq!(s.top1(g, Some("c"), None), (0, 2));
        assert_eq!(s.false_alarms(g, None), (1, 4));
        assert_eq!(s.false_alarms(GROUPS[2].1, None), (1, 1));
        // Drops of the counted cases: 10, 2, 5, 1, 1.25 → median 2.
        let (d, failed) = s.drop(g, None);
        assert!((d - 2.0).abs() < 1e-12, "median drop {d}");
        assert_eq!(failed, 0);
        assert_eq!(s.top1(GROUPS[2].1, None, None), (0, 1));

        let (rows, cols, m) = s.confusion(g);
        let at = |r: &str, c: &str| {
            let i = rows.iter().position(|x| x == r).unwrap();
            let j = cols.iter().position(|x| x == c).unwrap();
            m[i][j]
        };
        assert_eq!(rows.last().map(String::as_str), Some("control"));
        assert_eq!(cols.last().map(String::as_str), Some("none"));
        assert_eq!((at("a", "a"), at("a", "b")), (1, 1));
        assert_eq!(at("b", "b"), 1);
        assert_eq!((at("c", "none"), at("c", "c")), (1, 2));
        assert_eq!((at("control", "none"), at("control", "a")), (3, 1));
        let total: usize = m.iter().flatten().sum();
        assert_eq!(total, 10, "every ok case of the group, pairs aside, once");

        let t = s.threshold(g, "c");
        assert_eq!(t.n, 3);
        assert_eq!(t.smallest_found, 0.005);
        assert_eq!(t.largest_missed, 0.3);
        assert!(t.s90.is_nan(), "the largest sizes are missed");

        // The CSV holds the same matrix.
        let csv = s.confusion_csv();
        assert!(csv.contains("≥40 dB,control,none,3\n"), "{csv}");
        assert!(csv.contains("≥40 dB,c,c,2\n"), "{csv}");
        assert_eq!(s.cases_csv().lines().count(), cases.len() + 1);
    }

    /// A hidden effect reported as tied with the one named first counts as "first or tied",
    /// not as top-1; a tie on the wrong DOF of a chain counts as neither.
    #[test]
    fn ties_count_apart_from_top1() {
        let cat: Vec<String> = ["a", "b"].map(String::from).to_vec();
        let s40 = Some(40.0);
        let mut tied = case(Group::Single, &["a"], s40, 0.3, Some("b"), 1.0, 0.5);
        tied.rounds[0].tied = vec!["a".into()];
        let mut wrong_dof = case(Group::Single, &["a"], s40, 0.3, Some("b"), 1.0, 0.5);
        wrong_dof.rounds[0].tied = vec!["a@x2".into()];
        let right = case(Group::Single, &["b"], s40, 0.3, Some("b"), 1.0, 0.5);
        let cases = vec![tied, wrong_dof, right];
        let s = Summary::new(&cases, &cat);
        let g = GROUPS[0].1;
        assert_eq!(s.top1(g, None, None), (1, 3));
        assert_eq!(s.top1_or_tied(g), (2, 3));
    }

    /// Binning by the unrepresentable part and the "nothing detectable" reading: a case below
    /// its noise level's floor is answered acceptably by naming nothing or the hidden effect,
    /// and wrongly by naming another.
    #[test]
    fn bins_and_the_nothing_detectable_reading() {
        let cat: Vec<String> = ["a", "b"].map(String::from).to_vec();
        let (s40, s30) = (Some(40.0), Some(30.0));
        let with_part = |mut c: CaseResult, part: f64| {
            c.unrepresentable = vec![part];
            c
        };
        let cases = vec![
            // Large realised size, small unrepresentable part.
            with_part(case(Group::Single, &["a"], s40, 0.5, None, 1.0, 1.0), 0.01),
            with_part(
                case(Group::Single, &["a"], s40, 0.5, Some("b"), 1.0, 1.0),
                0.015,
            ),
            with_part(
                case(Group::Single, &["b"], s40, 0.5, Some("b"), 1.0, 0.1),
                0.3,
            ),
            with_part(
                case(Group::Single, &["b"], s40, 0.5, Some("b"), 1.0, 0.2),
                0.03,
            ),
            // 2.5 % is above the 40 dB floor (2 %), below the 30 dB one (3.16 %).
            with_part(case(Group::Single, &["b"], s30, 0.5, None, 1.0, 1.0), 0.025),
            with_part(
                case(Group::Single, &["a"], s30, 0.5, Some("a"), 1.0, 0.5),
                0.2,
            ),
        ];
        let s = Summary::new(&cases, &cat);
        let g = GROUPS[0].1;
        let small = s.binned(g, Measure::Unrepresentable, BINS[0]);
        assert_eq!((small.correct, small.n), (0, 2));
        let all = s.binned(g, Measure::Realised, BINS[3]);
        assert_eq!((all.correct, all.n), (2, 4));
        assert!(
            (all.drop - 3.0).abs() < 1e-12,
            "median of 1, 1, 10, 5: {}",
            all.drop
        );
        let d = s.detectable(g);
        assert_eq!((d.correct, d.n, d.quiet, d.n_quiet), (2, 2, 1, 2));
        assert!((s.detectable_drop(g) - 7.5).abs() < 1e-12);
        let d30 = s.detectable(GROUPS[1].1);
        assert_eq!((d30.correct, d30.n, d30.quiet, d30.n_quiet), (1, 1, 1, 1));
        // Half found from 3 % up: the 50 % threshold by part is 3 %; by realised size every
        // case is at 50 % and half of them are found.
        let t = s.threshold_by(g, "b", Measure::Unrepresentable, 0.5);
        assert_eq!(t.s90, 0.03);
        let t = s.threshold_by(g, "a", Measure::Unrepresentable, 0.5);
        assert!(t.s90.is_nan() && t.smallest_found.is_nan());
        assert!((floor(None) - MIN_SHARE).abs() < 1e-15);
        assert!((floor(Some(20.0)) - 0.1).abs() < 1e-12);
    }

    /// The split that best separates missed from found: none found, all found, a clean
    /// separation, and a mixed one where equally good splits take the highest.
    #[test]
    fn detection_limit_splits_missed_from_found() {
        let l = Limit::of(vec![(0.1, false), (0.3, false)]);
        assert!(l.at.is_nan() && l.above == (0, 0) && l.below == (0, 2));
        let l = Limit::of(vec![(0.3, true), (0.1, true)]);
        assert_eq!((l.at, l.above, l.below), (0.1, (2, 2), (0, 0)));
        let l = Limit::of(vec![(0.5, true), (0.01, false), (0.2, true), (0.05, false)]);
        assert_eq!(
            (l.at, l.below_max, l.above, l.below),
            (0.2, 0.05, (2, 2), (0, 2))
        );
        // Found, missed, found, found: splitting below everything or above the miss are both
        // one case wrong; the higher is taken.
        let l = Limit::of(vec![
            (0.01, true),
            (0.02, false),
            (0.03, true),
            (0.04, true),
        ]);
        assert_eq!((l.at, l.above, l.below), (0.03, (2, 2), (1, 2)));
    }

    #[test]
    fn median_of_even_odd_and_nan() {
        assert_eq!(median(vec![3.0, 1.0, 2.0]), 2.0);
        assert_eq!(median(vec![4.0, 1.0, f64::NAN, 2.0, 3.0]), 2.5);
        assert!(median(vec![f64::NAN]).is_nan());
    }
}
