//! The benchmark's outputs: `report.md`, the summary in `results.json`, and the figures.

use std::fmt::Write as _;
use std::path::Path;

use anyhow::Result;
use serde_json::{Value, json};
use tfs::plot::{Figure, LineChart, Series};
use tfs::signal::noise::SnrReference;

use super::Args;
use super::case::Group;
use super::summary::{Answers, BINS, GROUPS, MIN_SHARE, Measure, Summary, cell, floor};
use super::truth::Kind;
use crate::common::{f4, num, pct};

fn size(v: f64) -> String {
    if v.is_finite() { pct(v) } else { "—".into() }
}

/// A plain-text table with aligned columns, for the terminal.
fn text_table(out: &mut String, header: &[String], rows: &[Vec<String>]) {
    let width = |j: usize| {
        rows.iter()
            .map(|r| r[j].chars().count())
            .chain([header[j].chars().count()])
            .max()
            .unwrap_or(0)
    };
    let widths: Vec<usize> = (0..header.len()).map(width).collect();
    let line = |r: &[String]| {
        let cells: Vec<String> = r
            .iter()
            .zip(&widths)
            .enumerate()
            .map(|(j, (c, w))| {
                let pad = w - c.chars().count();
                if j == 0 {
                    format!("{c}{}", " ".repeat(pad))
                } else {
                    format!("{}{c}", " ".repeat(pad))
                }
            })
            .collect();
        cells.join("  ").trim_end().to_string()
    };
    let _ = writeln!(out, "{}", line(header));
    for r in rows {
        let _ = writeln!(out, "{}", line(r));
    }
}

/// One CSV field, quoted when it holds a comma, a quote or a line break.
fn csv_field(v: &str) -> String {
    if v.contains([',', '"', '\n']) {
        format!("\"{}\"", v.replace('"', "\"\""))
    } else {
        v.to_string()
    }
}

fn csv_line(out: &mut String, fields: &[String]) {
    let f: Vec<String> = fields.iter().map(|x| csv_field(x)).collect();
    let _ = writeln!(out, "{}", f.join(","));
}

fn opt(v: Option<f64>) -> String {
    v.filter(|x| x.is_finite())
        .map_or(String::new(), |x| format!("{x:.6e}"))
}

fn answers_json(a: Answers) -> Value {
    json!({"cases": a.n, "found": a.found, "missed_hidden_better": a.hidden_better,
           "missed_not_better": a.not_better, "missed_hidden_fails": a.hidden_fails,
           "reachable": a.found + a.hidden_better})
}

fn table(out: &mut String, header: &[&str], rows: &[Vec<String>]) {
    let _ = writeln!(out, "| {} |", header.join(" | "));
    let _ = writeln!(out, "|{}", "---|".repeat(header.len()));
    for r in rows {
        let _ = writeln!(out, "| {} |", r.join(" | "));
    }
    out.push('\n');
}

impl Summary<'_> {
    /// The per-effect table: accuracy and detection threshold per noise group, drops.
    fn effect_rows(&self) -> Vec<Vec<String>> {
        self.catalogue()
            .iter()
            .map(|e| {
                let mut row = vec![format!("`{e}`")];
                for (_, g) in GROUPS {
                    let (c, n) = self.top1(g, Some(e), None);
                    row.push(cell(c, n));
                }
                for (_, g) in GROUPS {
                    let t = self.threshold_by(g, e, Measure::Unrepresentable, 0.9);
                    row.push(if t.n == 0 {
                        "—".into()
                    } else if t.s90.is_finite() {
                        size(t.s90)
                    } else {
                        format!("not found (up to {})", size(t.largest_missed))
                    });
                }
                let g = GROUPS[0].1;
                let (d, failed) = self.drop(g, Some(e));
                row.push(if failed > 0 {
                    format!("{}× ({failed} failed)", f4(d))
                } else {
                    format!("{}×", f4(d))
                });
                row.push(format!("{}×", f4(self.oracle_drop(g, e))));
                row
            })
            .collect()
    }

    /// The report.
    pub fn markdown(&self, args: &Args, seconds: f64) -> String {
        let mut s = String::new();
        let cmd = args.command();
        let _ = writeln!(s, "# Diagnosis benchmark\n");
        let _ = writeln!(
            s,
            "`{cmd}` (seed {}), {} cases in {:.0} s. {}\n",
            args.seed,
            self.cases().len(),
            seconds,
            self.headline()
        );
        let _ = writeln!(
            s,
            "Every effect of the standard catalogue is hidden in truths the tool has never seen; each case draws its baseline's parameters and excitations, the effect's parameters and element, its size (the RMS of its force over the RMS of the acceleration, log-uniform over {}–{} in strata) and the noise draw (white, on every measured channel, its level relative to the channel's {}). Three training records and a held-out one; `identify` with the start library (without the effect), `diagnose`, `refit --add <top effect>`, all through the `tfs` library. Top-1 counts the first significant effect (on an admissible DOF for chains) over cases whose realised size is at least the diagnosis's minimum size ({}); the held-out drop is the held-out prediction R-MSE before over after adding the top effect (1× when nothing was added), each case's models scored by one ruler chosen from its start model: the free run under the measured input, or, where a fresh draw of the input's own noise moves the start model's free run about as far as its error (chaotic snap-through), pieces as long as its predictions from the measured state keep their skill; the oracle drop adds the hidden effect itself. The unrepresentable part of an effect is the RMS of what the best least-squares fit of its force by the start library's columns (clean training states, one set of coefficients over the three records, as `identify` fits them) leaves, over the RMS acceleration: what any model from the start library must miss. The detection threshold (\"90 % part\") is the smallest unrepresentable part above which at least 90 % of the cases are found first.\n",
            pct(super::SIZES.0),
            pct(super::SIZES.1),
            match args.snr_reference {
                SnrReference::MeanSquare => "mean square, its static operating point included",
                SnrReference::Variance => "variance, its motion about the mean",
            },
            pct(MIN_SHARE)
        );
        let _ = writeln!(s, "## Per effect\n");
        table(
            &mut s,
            &[
                "effect",
                "top-1 ≥40 dB",
                "top-1 30 dB",
                "top-1 20 dB",
                "90 % part ≥40 dB",
                "90 % part 30 dB",
                "90 % part 20 dB",
                "median drop ≥40 dB",
                "oracle drop ≥40 dB",
            ],
            &self.effect_rows(),
        );
        self.missing_sections(&mut s);
        let _ = writeln!(s, "## Per baseline\n");
        let rows: Vec<Vec<String>> = Kind::ALL
            .iter()
            .filter(|k| self.cases().iter().any(|c| c.spec.kind == **k))
            .map(|&k| {
                let mut r = vec![k.key().to_string()];
                for (_, g) in GROUPS {
                    let (c, n) = self.top1(g, None, Some(k));
                    r.push(cell(c, n));
                }
                let (fa, nc) = self.false_alarms(GROUPS[0].1, Some(k));
                r.push(cell(fa, nc));
                let (fa, nc) = self.false_alarms(&[Some(30.0), Some(20.0)], Some(k));
                r.push(cell(fa, nc));
                let (med, max) = self.times(Some(k));
                r.push(format!("{} / {}", f4(med), f4(max)));
                r
            })
            .collect();
        table(
            &mut s,
            &[
                "baseline",
                "top-1 ≥40 dB",
                "top-1 30 dB",
                "top-1 20 dB",
                "false alarms ≥40 dB",
                "false alarms 30/20 dB",
                "s per case (median / max)",
            ],
            &rows,
        );
        for k in Kind::ALL {
            let _ = writeln!(s, "- **{}**: {}", k.key(), k.describe());
        }
        s.push('\n');
        let _ = writeln!(s, "## Two hidden effects, two rounds\n");
        let rows: Vec<Vec<String>> = [
            ("noise-free", &[None][..]),
            ("40 dB", &[Some(40.0)]),
            ("30 dB", &[Some(30.0)]),
        ]
        .iter()
        .map(|(name, g)| {
            let (b, n, d) = self.pairs(g);
            vec![name.to_string(), cell(b, n), format!("{}×", f4(d))]
        })
        .collect();
        table(
            &mut s,
            &[
                "noise",
                "both found, one per round",
                "median drop after two rounds",
            ],
            &rows,
        );
        let _ = writeln!(
            s,
            "## Confusion matrix (≥40 dB; rows hidden, columns named first)\n"
        );
        let (header, body) = self.confusion_cells(GROUPS[0].1);
        table(
            &mut s,
            &header.iter().map(String::as_str).collect::<Vec<_>>(),
            &body,
        );
        let _ = writeln!(
            s,
            "The same matrix for every noise group is in `confusion.csv`; every case in `cases.csv` and `results.json`.\n\n![detection against effect size](detection.png)\n"
        );
        let (med, max) = self.times(None);
        let _ = writeln!(
            s,
            "## Time per case\n\nMedian {} s, longest {} s (identify, diagnose and refit of three training records, the held-out scores and the truth's simulations; cases run two at a time).\n",
            f4(med),
            f4(max)
        );
        let failed: Vec<String> = self
            .cases()
            .iter()
            .filter(|c| !c.ok() && c.status != "not-applicable")
            .map(|c| {
                format!(
                    "- case {} ({}, {:?}, {}): {} — {}",
                    c.spec.id,
                    c.spec.kind.key(),
                    c.spec.hidden,
                    c.spec
                        .snr
                        .map_or("noise-free".into(), |v| format!("{v} dB")),
                    c.status,
                    c.message.clone().unwrap_or_default()
                )
            })
            .collect();
        let na = self
            .cases()
            .iter()
            .filter(|c| c.status == "not-applicable")
            .count();
        let _ = writeln!(
            s,
            "## Cases that did not run\n\n{} not applicable (the effect has no truth on that baseline, e.g. an offset where the start library has the constant). {} others:\n",
            na,
            failed.len()
        );
        for f in failed {
            let _ = writeln!(s, "{f}");
        }
        let small = self
            .cases()
            .iter()
            .filter(|c| c.ok() && c.spec.group == Group::Single)
            .filter(|c| c.realised.first().is_some_and(|s| *s < MIN_SHARE))
            .count();
        let _ = writeln!(
            s,
            "\n{small} single-effect cases came out below the minimum size and are not counted in top-1 (they are in the thresholds)."
        );
        s
    }

    /// The misses sorted by what the held-out record says of the hidden effect added by name,
    /// and the top-1 a ranking would reach that missed only where that record gives no reason
    /// to prefer the hidden effect.
    fn answers_section(&self, s: &mut String, groups: &[(&str, &[Option<f64>])]) {
        let _ = writeln!(
            s,
            "### What the held-out record says of each miss\n\nEach missed case is refitted with its hidden effect added by name (the oracle) and both models predict the held-out record: the hidden effect predicts it better than the answer given (the model with the effect named first, or the start model when nothing was named; an answer that fails to simulate counts as beaten), or no better, or its refit does not simulate it. Only the first kind is a miss the records tell: \"reachable\" is the top-1 of a ranking that missed only the other two, a bound on what choosing among the catalogue by these records can give (one held-out record decides, so it is itself a noisy reading). \"Detectable\" restricts to cases whose unrepresentable part reaches the detection floor.\n"
        );
        let rows: Vec<Vec<String>> = groups
            .iter()
            .flat_map(|(name, g)| {
                [false, true].map(|det| {
                    let a = self.answers(g, det);
                    vec![
                        format!("{name}{}", if det { ", detectable" } else { "" }),
                        cell(a.found, a.n),
                        a.hidden_better.to_string(),
                        a.not_better.to_string(),
                        a.hidden_fails.to_string(),
                        cell(a.found + a.hidden_better, a.n),
                    ]
                })
            })
            .collect();
        table(
            s,
            &[
                "noise",
                "top-1",
                "missed: hidden effect predicts better",
                "missed: no better",
                "missed: hidden effect does not simulate",
                "reachable",
            ],
            &rows,
        );
    }

    /// The report's sections on the unrepresentable part: scores binned by it beside the
    /// realised size, the "nothing detectable" reading, and where detection stops per effect.
    fn missing_sections(&self, s: &mut String) {
        let groups: Vec<(&str, &[Option<f64>])> = GROUPS
            .iter()
            .copied()
            .filter(|(_, g)| {
                self.cases()
                    .iter()
                    .any(|c| c.ok() && g.contains(&c.spec.snr))
            })
            .collect();
        if groups.is_empty() {
            return;
        }
        let _ = writeln!(
            s,
            "## By the part of the effect the start library cannot hold\n\nEvery single-effect case (also those below the minimum size), binned by its realised size and by its unrepresentable part; each cell is top-1 and the median held-out drop.\n"
        );
        let mut header = vec!["bin".to_string()];
        for (name, _) in &groups {
            header.push(format!("{name}, by size"));
            header.push(format!("{name}, by unrepresentable part"));
        }
        let rows: Vec<Vec<String>> = BINS
            .iter()
            .map(|&(lo, hi)| {
                let mut r = vec![if hi.is_finite() {
                    format!("{}–{}", pct(lo), pct(hi))
                } else {
                    format!("≥ {}", pct(lo))
                }];
                for (_, g) in &groups {
                    for m in [Measure::Realised, Measure::Unrepresentable] {
                        let b = self.binned(g, m, (lo, hi));
                        r.push(if b.n == 0 {
                            "—".into()
                        } else {
                            format!("{}, {}×", cell(b.correct, b.n), f4(b.drop))
                        });
                    }
                }
                r
            })
            .collect();
        table(
            s,
            &header.iter().map(String::as_str).collect::<Vec<_>>(),
            &rows,
        );
        let _ = writeln!(
            s,
            "### The \"nothing detectable\" reading\n\nA case is *undetectable* when its unrepresentable part is below the detection floor of its noise level: the larger of the diagnosis's minimum size ({}) and the records' relative noise amplitude 10^(−SNR/20) (noise-free {}, 40 dB {}, 30 dB {}, 20 dB {}). There, whatever the coefficients, a model from the start library misses less than the tool is built to report or than the noise on each channel, and \"nothing significant\" is an acceptable answer (so is the hidden effect itself; another effect is not). This is a second reading beside the headline, not a replacement: the headline counts every case of at least the minimum realised size.\n",
            pct(MIN_SHARE),
            pct(floor(None)),
            pct(floor(Some(40.0))),
            pct(floor(Some(30.0))),
            pct(floor(Some(20.0)))
        );
        let rows: Vec<Vec<String>> = groups
            .iter()
            .map(|(name, g)| {
                let d = self.detectable(g);
                let (fa, nc) = self.false_alarms(g, None);
                vec![
                    name.to_string(),
                    cell(d.correct, d.n),
                    format!("{}×", f4(self.detectable_drop(g))),
                    cell(d.quiet, d.n_quiet),
                    cell(d.correct + d.quiet, d.n + d.n_quiet),
                    cell(fa, nc),
                ]
            })
            .collect();
        table(
            s,
            &[
                "noise",
                "detectable: top-1",
                "detectable: median drop",
                "undetectable: nothing or the effect named",
                "all single cases, this reading",
                "false alarms on controls",
            ],
            &rows,
        );
        self.answers_section(s, &groups);
        let _ = writeln!(
            s,
            "### Where detection stops, effect by effect\n\nPer effect (all baselines of the run together) and noise level, the cases sorted by unrepresentable part are split where the split best separates those missed (below) from those found first (above); equally good splits take the highest. The cell gives the smallest part above the split, how many cases are found first above and below it, and (size) the same split made on realised size. \"Not detected\" when the best split leaves every case below: in no range of sizes from some size up are more cases found than missed.\n"
        );
        let mut header = vec!["effect".to_string()];
        header.extend(groups.iter().map(|(n, _)| n.to_string()));
        let rows: Vec<Vec<String>> = self
            .catalogue()
            .iter()
            .map(|e| {
                let mut r = vec![format!("`{e}`")];
                for (_, g) in &groups {
                    let p = self.limit(g, e, Measure::Unrepresentable);
                    let z = self.limit(g, e, Measure::Realised);
                    let n = p.above.1 + p.below.1;
                    r.push(if n == 0 {
                        "—".into()
                    } else if p.at.is_finite() {
                        format!(
                            "part {} (size {}): {}/{} found above, {}/{} below",
                            size(p.at),
                            size(z.at),
                            p.above.0,
                            p.above.1,
                            p.below.0,
                            p.below.1
                        )
                    } else {
                        format!(
                            "not detected ({}/{} found; part up to {})",
                            p.below.0,
                            n,
                            size(p.below_max)
                        )
                    });
                }
                r
            })
            .collect();
        table(
            s,
            &header.iter().map(String::as_str).collect::<Vec<_>>(),
            &rows,
        );
    }

    /// The confusion matrix of noise group `g` (rows hidden, and "control"; columns named
    /// first, and "none"), trimmed to the rows and columns that hold a case: header and rows.
    fn confusion_cells(&self, g: &[Option<f64>]) -> (Vec<String>, Vec<Vec<String>>) {
        let (rows, cols, m) = self.confusion(g);
        let used: Vec<usize> = (0..cols.len())
            .filter(|&j| m.iter().any(|r| r[j] > 0))
            .collect();
        let mut header = vec!["hidden \\ named first".to_string()];
        header.extend(used.iter().map(|&j| cols[j].clone()));
        let body: Vec<Vec<String>> = rows
            .iter()
            .zip(&m)
            .filter(|(_, r)| r.iter().any(|&v| v > 0))
            .map(|(name, r)| {
                let mut row = vec![name.clone()];
                row.extend(used.iter().map(|&j| match r[j] {
                    0 => "·".to_string(),
                    v => v.to_string(),
                }));
                row
            })
            .collect();
        (header, body)
    }

    /// The confusion matrix of noise group `g` as aligned text.
    fn confusion_text(&self, out: &mut String, g: &[Option<f64>]) {
        let (header, body) = self.confusion_cells(g);
        if body.is_empty() {
            let _ = writeln!(out, "(no case ran)");
        } else {
            text_table(out, &header, &body);
        }
    }

    /// What the terminal shows: per noise group that ran, the headline numbers and the
    /// confusion matrix; then the per-effect table at the noise levels that ran.
    pub fn terminal(&self) -> String {
        let mut s = String::new();
        for (name, g) in GROUPS {
            if !self
                .cases()
                .iter()
                .any(|c| c.ok() && g.contains(&c.spec.snr))
            {
                continue;
            }
            let (c, n) = self.top1(g, None, None);
            let (fa, nc) = self.false_alarms(g, None);
            let (d, failed) = self.drop(g, None);
            let _ = writeln!(s, "\n{name}:");
            let _ = writeln!(s, "  top-1 correct                  {}", cell(c, n));
            let (ct, nt) = self.top1_or_tied(g);
            let _ = writeln!(s, "  first or tied with the first   {}", cell(ct, nt));
            let _ = writeln!(s, "  false alarms on controls       {}", cell(fa, nc));
            let _ = writeln!(
                s,
                "  median held-out error drop     {}× after the top effect{}",
                f4(d),
                if failed > 0 {
                    format!(" ({failed} simulations failed)")
                } else {
                    String::new()
                }
            );
            let d = self.detectable(g);
            let _ = writeln!(
                s,
                "  detectable (part ≥ {}): top-1 {}; undetectable: nothing or the effect named {}",
                pct(floor(g.last().copied().flatten())),
                cell(d.correct, d.n),
                cell(d.quiet, d.n_quiet)
            );
            let a = self.answers(g, false);
            let _ = writeln!(
                s,
                "  misses the records tell        {} of {} (top-1 reachable {})",
                a.hidden_better,
                a.n - a.found,
                cell(a.found + a.hidden_better, a.n)
            );
            let (pb, pn, pd) = self.pairs(g);
            if pn > 0 {
                let _ = writeln!(
                    s,
                    "  two hidden, both found         {}; median drop after two rounds {}×",
                    cell(pb, pn),
                    f4(pd)
                );
            }
            let _ = writeln!(s);
            self.confusion_text(&mut s, g);
        }
        let header: Vec<String> = ["effect", "top-1", "median drop", "oracle drop", "cases"]
            .map(String::from)
            .to_vec();
        let all: Vec<Option<f64>> = GROUPS.iter().flat_map(|(_, g)| g.to_vec()).collect();
        let rows: Vec<Vec<String>> = self
            .catalogue()
            .iter()
            .filter_map(|e| {
                let (c, n) = self.top1(&all, Some(e), None);
                (n > 0).then(|| {
                    vec![
                        e.clone(),
                        cell(c, n),
                        format!("{}×", f4(self.drop(&all, Some(e)).0)),
                        format!("{}×", f4(self.oracle_drop(&all, e))),
                        n.to_string(),
                    ]
                })
            })
            .collect();
        if !rows.is_empty() {
            let _ = writeln!(s, "\nPer effect (all noise levels that ran):");
            text_table(&mut s, &header, &rows);
        }
        s
    }

    /// `confusion.csv`: one line per noise group, hidden effect (or control) and named effect
    /// (or none) with its count; cells with no case are left out.
    pub fn confusion_csv(&self) -> String {
        let mut s = String::new();
        csv_line(
            &mut s,
            &["noise", "hidden", "named_first", "cases"].map(String::from),
        );
        for (name, g) in GROUPS {
            let (rows, cols, m) = self.confusion(g);
            for (r, counts) in rows.iter().zip(&m) {
                for (c, &v) in cols.iter().zip(counts) {
                    if v > 0 {
                        csv_line(
                            &mut s,
                            &[name.to_string(), r.clone(), c.clone(), v.to_string()],
                        );
                    }
                }
            }
        }
        s
    }

    /// `cases.csv`: one line per case with what was hidden, its size, what was named and the
    /// held-out errors.
    pub fn cases_csv(&self) -> String {
        let mut s = String::new();
        csv_line(
            &mut s,
            &[
                "id",
                "baseline",
                "group",
                "hidden",
                "snr_db",
                "target_size",
                "realised_size",
                "unrepresentable_part",
                "status",
                "named_first",
                "correct",
                "heldout_score",
                "heldout_before",
                "heldout_after",
                "oracle_after",
                "named_second",
                "heldout_after_second",
                "seconds",
            ]
            .map(String::from),
        );
        for c in self.cases() {
            let r1 = c.rounds.first();
            let r2 = c.rounds.get(1);
            csv_line(
                &mut s,
                &[
                    c.spec.id.to_string(),
                    c.spec.kind.key().to_string(),
                    format!("{:?}", c.spec.group).to_lowercase(),
                    c.spec.hidden.join("+"),
                    c.spec.snr.map_or("clean".into(), |v| v.to_string()),
                    c.spec
                        .sizes
                        .iter()
                        .map(|v| format!("{v:.4}"))
                        .collect::<Vec<_>>()
                        .join("+"),
                    c.realised
                        .iter()
                        .map(|v| format!("{v:.4}"))
                        .collect::<Vec<_>>()
                        .join("+"),
                    c.unrepresentable
                        .iter()
                        .map(|v| format!("{v:.4}"))
                        .collect::<Vec<_>>()
                        .join("+"),
                    c.status.clone(),
                    r1.and_then(|r| r.top.clone())
                        .unwrap_or_else(|| if c.ok() { "none".into() } else { String::new() }),
                    if c.ok() && c.spec.group != Group::Control {
                        c.top1_correct().to_string()
                    } else {
                        String::new()
                    },
                    c.heldout_score
                        .as_ref()
                        .map_or(String::new(), |s| s.label()),
                    opt(r1.and_then(|r| r.before)),
                    opt(r1.and_then(|r| r.after)),
                    opt(c.oracle_after),
                    r2.and_then(|r| r.top.clone()).unwrap_or_default(),
                    opt(r2.and_then(|r| r.after)),
                    format!("{:.3}", c.seconds),
                ],
            );
        }
        s
    }

    /// The summary as JSON.
    pub fn to_json(&self) -> Value {
        let groups: Vec<Value> = GROUPS
            .iter()
            .map(|(name, g)| {
                let (c, n) = self.top1(g, None, None);
                let (fa, nc) = self.false_alarms(g, None);
                let (d, failed) = self.drop(g, None);
                let (pb, pn, pd) = self.pairs(g);
                let (rows, cols, m) = self.confusion(g);
                let effects: Vec<Value> = self
                    .catalogue()
                    .iter()
                    .map(|e| {
                        let (c, n) = self.top1(g, Some(e), None);
                        let t = self.threshold(g, e);
                        let p50 = self.threshold_by(g, e, Measure::Unrepresentable, 0.5);
                        let z50 = self.threshold_by(g, e, Measure::Realised, 0.5);
                        json!({"effect": e, "correct": c, "cases": n,
                               "part_50": num(p50.s90), "size_50": num(z50.s90),
                               "part_smallest_found": num(p50.smallest_found),
                               "part_largest_missed": num(p50.largest_missed),
                               "threshold_s90": num(t.s90), "smallest_found": num(t.smallest_found),
                               "largest_missed": num(t.largest_missed), "sized_cases": t.n,
                               "median_drop": num(self.drop(g, Some(e)).0),
                               "oracle_drop": num(self.oracle_drop(g, e))})
                    })
                    .collect();
                let det = self.detectable(g);
                let bins: Vec<Value> = BINS
                    .iter()
                    .map(|&(lo, hi)| {
                        let z = self.binned(g, Measure::Realised, (lo, hi));
                        let p = self.binned(g, Measure::Unrepresentable, (lo, hi));
                        json!({"lo": lo, "hi": num(hi),
                               "by_size": {"correct": z.correct, "cases": z.n, "median_drop": num(z.drop)},
                               "by_part": {"correct": p.correct, "cases": p.n, "median_drop": num(p.drop)}})
                    })
                    .collect();
                json!({
                    "noise": name,
                    "bins": bins,
                    "detectable": {"correct": det.correct, "cases": det.n,
                                   "median_drop": num(self.detectable_drop(g)),
                                   "undetectable_quiet": det.quiet, "undetectable": det.n_quiet},
                    "top1_correct": c, "top1_cases": n, "top1": num(c as f64 / n.max(1) as f64),
                    "top1_or_tied": self.top1_or_tied(g).0,
                    "answers": answers_json(self.answers(g, false)),
                    "answers_detectable": answers_json(self.answers(g, true)),
                    "false_alarms": fa, "controls": nc,
                    "median_drop": num(d), "drop_failed": failed,
                    "pairs_both_found": pb, "pairs": pn, "pairs_median_drop": num(pd),
                    "confusion": {"rows": rows, "columns": cols, "counts": m},
                    "effects": effects,
                })
            })
            .collect();
        let (med, max) = self.times(None);
        json!({"groups": groups, "seconds_per_case_median": num(med), "seconds_per_case_max": num(max), "min_share": MIN_SHARE})
    }

    /// `confusion.{svg,png}` and `detection.{svg,png}`.
    pub fn figures(&self, dir: &Path) -> Result<()> {
        // Detection rate in bins of a factor 2 of the realised size (solid) and of the
        // unrepresentable part (dashed), per noise group.
        let mut chart = LineChart::new(
            "Top-1 detection against effect size (all effects and baselines)",
            "size: log10(force RMS / acceleration RMS); solid realised, dashed unrepresentable part",
            "share of cases found first",
        );
        for (name, g) in GROUPS {
            for m in [Measure::Realised, Measure::Unrepresentable] {
                let sized = self.single_sized(g, m);
                let pts: Vec<(f64, f64)> = (0..12)
                    .filter_map(|b| {
                        let lo = 0.005 * 2f64.powi(b);
                        let v: Vec<bool> = sized
                            .iter()
                            .filter(|(s, _)| *s >= lo && *s < 2.0 * lo)
                            .map(|(_, ok)| *ok)
                            .collect();
                        (v.len() >= 3).then(|| {
                            let f = v.iter().filter(|x| **x).count() as f64 / v.len() as f64;
                            ((lo * 2f64.sqrt()).log10(), f)
                        })
                    })
                    .collect();
                if pts.len() >= 2 {
                    chart = chart.with_series(match m {
                        Measure::Realised => Series::line(format!("{name}, realised size"), pts),
                        Measure::Unrepresentable => {
                            Series::dashed(format!("{name}, unrepresentable part"), pts)
                        }
                    });
                }
            }
        }
        chart = chart.with_vline(MIN_SHARE.log10(), "minimum size");
        Figure::from(chart).save(&dir.join("detection"))?;
        Ok(())
    }
}
