//! The reproduction report: studies made of text, tables (markdown + CSV + HTML) and figures
//! (SVG + PNG through tfs-plot), the `results.json` tree and the paper-vs-ours summary.

use std::fmt::Write as _;
use std::path::{Path, PathBuf};

use anyhow::{Context, Result};
use serde_json::{Map, Value, json};
use tfs::plot::Figure;

/// A table: written as `<name>.csv`, and shown in the markdown and HTML reports.
#[derive(Debug, Clone)]
pub struct Table {
    /// File stem of the CSV.
    pub name: String,
    /// Caption.
    pub caption: String,
    /// Column headers.
    pub header: Vec<String>,
    /// Rows of formatted cells.
    pub rows: Vec<Vec<String>>,
}

impl Table {
    /// A table with a header and no rows yet.
    pub fn new(name: &str, caption: &str, header: &[&str]) -> Self {
        Self {
            name: name.to_string(),
            caption: caption.to_string(),
            header: header.iter().map(|s| s.to_string()).collect(),
            rows: Vec::new(),
        }
    }

    /// Appends a row.
    pub fn row(&mut self, cells: Vec<String>) {
        self.rows.push(cells);
    }

    fn csv(&self) -> String {
        let esc = |s: &str| {
            if s.contains([',', '"', '\n']) {
                format!("\"{}\"", s.replace('"', "\"\""))
            } else {
                s.to_string()
            }
        };
        let mut out = String::new();
        let line = |cells: &[String]| cells.iter().map(|c| esc(c)).collect::<Vec<_>>().join(",");
        out.push_str(&line(&self.header));
        out.push('\n');
        for r in &self.rows {
            out.push_str(&line(r));
            out.push('\n');
        }
        out
    }

    fn markdown(&self) -> String {
        let mut s = format!("**{}** (`tables/{}.csv`)\n\n", self.caption, self.name);
        let cell = |c: &str| c.replace('|', "\\|");
        s.push_str(&format!(
            "| {} |\n",
            self.header
                .iter()
                .map(|c| cell(c))
                .collect::<Vec<_>>()
                .join(" | ")
        ));
        s.push_str(&format!("|{}\n", "---|".repeat(self.header.len())));
        for r in &self.rows {
            s.push_str(&format!(
                "| {} |\n",
                r.iter().map(|c| cell(c)).collect::<Vec<_>>().join(" | ")
            ));
        }
        s
    }

    /// The table as HTML; `row_class(i)` gives row `i` a CSS class (e.g. `fail`).
    fn html_with<'a>(&self, row_class: impl Fn(usize) -> Option<&'a str>) -> String {
        let mut s = format!(
            "<table><caption>{} (<a href=\"tables/{}.csv\">CSV</a>)</caption>\n<tr>",
            esc_html(&self.caption),
            self.name
        );
        for h in &self.header {
            let _ = write!(s, "<th>{}</th>", esc_html(h));
        }
        s.push_str("</tr>\n");
        for (i, r) in self.rows.iter().enumerate() {
            match row_class(i) {
                Some(c) => {
                    let _ = write!(s, "<tr class=\"{c}\">");
                }
                None => s.push_str("<tr>"),
            }
            for c in r {
                let _ = write!(s, "<td>{}</td>", esc_html(c));
            }
            s.push_str("</tr>\n");
        }
        s.push_str("</table>\n");
        s
    }
}

fn esc_html(s: &str) -> String {
    s.replace('&', "&amp;")
        .replace('<', "&lt;")
        .replace('>', "&gt;")
}

/// One piece of a study's section.
#[derive(Debug, Clone)]
enum Block {
    Text(String),
    Table(Table),
    Figure { stem: String, caption: String },
}

/// One row of the printed summary: what is compared, the truth it estimates, our number and the
/// paper's beside it, and whether ours passes its check.
#[derive(Debug, Clone, serde::Serialize)]
pub struct SummaryRow {
    /// What is compared.
    pub metric: String,
    /// The value our number estimates (the simulated truth), or what the check compares against.
    pub truth: String,
    /// Our value, with its deviation from the truth where there is one.
    pub ours: String,
    /// The paper's value, with its deviation from the truth and from ours where there is one.
    pub paper: String,
    /// The check passed (`Some(true)`), failed (`Some(false)`) or there is none (`None`:
    /// informational row).
    pub within_tolerance: Option<bool>,
    /// The check's rule: what ours is judged against.
    pub rule: String,
}

impl SummaryRow {
    /// A row whose check failed: ours is outside the rule.
    pub fn failed(&self) -> bool {
        self.within_tolerance == Some(false)
    }
}

/// A study being filled: its section blocks, its `results.json` subtree and summary rows.
pub struct Study {
    /// Key in `results.json` (e.g. `s1_white`).
    pub key: String,
    /// Section title.
    pub title: String,
    out: PathBuf,
    blocks: Vec<Block>,
    /// Every number of the study.
    pub results: Map<String, Value>,
    summary: Vec<SummaryRow>,
}

impl Study {
    /// A new study writing its files under `out`.
    pub fn new(key: &str, title: &str, out: &Path) -> Self {
        Self {
            key: key.to_string(),
            title: title.to_string(),
            out: out.to_path_buf(),
            blocks: Vec::new(),
            results: Map::new(),
            summary: Vec::new(),
        }
    }

    /// The report's output folder (for files a study writes besides its tables and figures).
    pub fn out_dir(&self) -> &Path {
        &self.out
    }

    /// Adds a paragraph (markdown; shown pre-formatted-free in HTML).
    pub fn text(&mut self, s: impl Into<String>) {
        self.blocks.push(Block::Text(s.into()));
    }

    /// Writes the table's CSV and adds it to the section.
    pub fn table(&mut self, t: Table) -> Result<()> {
        let dir = self.out.join("tables");
        std::fs::create_dir_all(&dir).with_context(|| format!("creating {}", dir.display()))?;
        let p = dir.join(format!("{}.csv", t.name));
        tfs::data::write_atomic(&p, t.csv()).with_context(|| format!("writing {}", p.display()))?;
        self.blocks.push(Block::Table(t));
        Ok(())
    }

    /// Saves a figure as `figures/<stem>.svg` and `.png` and adds it to the section.
    pub fn figure(&mut self, stem: &str, caption: &str, fig: impl Into<Figure>) -> Result<()> {
        let fig: Figure = fig.into();
        let path = self.out.join("figures").join(stem);
        fig.save(&path).with_context(|| format!("figure {stem}"))?;
        self.blocks.push(Block::Figure {
            stem: stem.to_string(),
            caption: caption.to_string(),
        });
        Ok(())
    }

    /// Copies an existing figure `<dir>/<stem>.svg` and `.png` into `figures/` and adds it to the
    /// section.
    pub fn copied_figure(&mut self, dir: &Path, stem: &str, caption: &str) -> Result<()> {
        let to = self.out.join("figures");
        std::fs::create_dir_all(&to).with_context(|| format!("creating {}", to.display()))?;
        for ext in ["svg", "png"] {
            let from = dir.join(format!("{stem}.{ext}"));
            std::fs::read(&from)
                .and_then(|bytes| tfs::data::write_atomic(to.join(format!("{stem}.{ext}")), bytes))
                .with_context(|| format!("copying {}", from.display()))?;
        }
        self.blocks.push(Block::Figure {
            stem: stem.to_string(),
            caption: caption.to_string(),
        });
        Ok(())
    }

    /// Stores a value in the study's results.
    pub fn set(&mut self, key: &str, v: Value) {
        self.results.insert(key.to_string(), v);
    }

    /// The summary rows added so far.
    #[cfg(test)]
    pub fn summary_rows(&self) -> &[SummaryRow] {
        &self.summary
    }

    /// Adds a summary row: `metric`, the `truth` it estimates, `ours` and the `paper`'s value
    /// (each with its deviations), the check's outcome (`None`: informational) and its `rule`.
    pub fn compare(
        &mut self,
        metric: &str,
        truth: &str,
        ours: &str,
        paper: &str,
        ok: Option<bool>,
        rule: &str,
    ) {
        self.summary.push(SummaryRow {
            metric: metric.to_string(),
            truth: truth.to_string(),
            ours: ours.to_string(),
            paper: paper.to_string(),
            within_tolerance: ok,
            rule: rule.to_string(),
        });
    }
}

/// The whole report.
pub struct Report {
    out: PathBuf,
    quick: bool,
    studies: Vec<(Study, Option<String>, f64)>,
}

impl Report {
    /// An empty report for `out`.
    pub fn new(out: &Path, quick: bool) -> Self {
        Self {
            out: out.to_path_buf(),
            quick,
            studies: Vec::new(),
        }
    }

    /// Adds a finished (or failed: `error`) study with its wall time.
    pub fn push(&mut self, study: Study, error: Option<String>, seconds: f64) {
        self.studies.push((study, error, seconds));
    }

    /// All summary rows, in study order.
    pub fn summary(&self) -> Vec<&SummaryRow> {
        self.studies
            .iter()
            .flat_map(|(s, _, _)| s.summary.iter())
            .collect()
    }

    /// Names and errors of the studies that failed.
    pub fn failures(&self) -> Vec<(String, String)> {
        self.studies
            .iter()
            .filter_map(|(s, e, _)| e.as_ref().map(|e| (s.key.clone(), e.clone())))
            .collect()
    }

    /// Writes `results.json`, `report.md` and `index.html`.
    pub fn write(&self, total_seconds: f64, preamble: &str) -> Result<()> {
        let mut studies = Map::new();
        for (s, err, secs) in &self.studies {
            let mut v = s.results.clone();
            v.insert("title".into(), json!(s.title));
            v.insert("seconds".into(), json!(secs));
            v.insert(
                "error".into(),
                err.as_ref().map_or(Value::Null, |e| json!(e)),
            );
            studies.insert(s.key.clone(), Value::Object(v));
        }
        let results = json!({
            "format": "tfs-reproduce-paper/1",
            "quick": self.quick,
            "total_seconds": total_seconds,
            "studies": studies,
            "summary": self.summary(),
            "failed_studies": self.failures().iter().map(|(k, _)| k.clone()).collect::<Vec<_>>(),
        });
        let p = self.out.join("results.json");
        tfs::data::write_atomic(&p, serde_json::to_string_pretty(&results)?)
            .with_context(|| format!("writing {}", p.display()))?;
        tfs::data::write_atomic(
            self.out.join("report.md"),
            self.markdown(total_seconds, preamble),
        )
        .context("writing report.md")?;
        tfs::data::write_atomic(
            self.out.join("index.html"),
            self.html(total_seconds, preamble),
        )
        .context("writing index.html")?;
        Ok(())
    }

    /// The summary rows whose check failed.
    pub fn failed_checks(&self) -> Vec<&SummaryRow> {
        self.summary().into_iter().filter(|r| r.failed()).collect()
    }

    fn summary_table(&self) -> Table {
        let mut t = Table::new(
            "summary",
            "Summary: each number judged against the truth it estimates, the paper's beside it",
            &[
                "check",
                "truth",
                "ours (vs truth)",
                "paper (vs truth)",
                "verdict",
                "rule",
            ],
        );
        for r in self.summary() {
            t.row(vec![
                r.metric.clone(),
                r.truth.clone(),
                r.ours.clone(),
                r.paper.clone(),
                verdict(r.within_tolerance).to_string(),
                r.rule.clone(),
            ]);
        }
        t
    }

    /// Writes the summary CSV (called by [`Report::write`]'s caller before printing).
    pub fn write_summary_csv(&self) -> Result<()> {
        let dir = self.out.join("tables");
        std::fs::create_dir_all(&dir)?;
        tfs::data::write_atomic(dir.join("summary.csv"), self.summary_table().csv())?;
        Ok(())
    }

    /// The verdict in a few sentences (Markdown): how many checks pass, and each failure with
    /// its numbers and rule.
    pub fn verdict_text(&self) -> String {
        let rows = self.summary();
        let checks = rows.iter().filter(|r| r.within_tolerance.is_some()).count();
        let failed = self.failed_checks();
        let studies = self.failures();
        let mut s = String::new();
        if failed.is_empty() && studies.is_empty() {
            let _ = writeln!(
                s,
                "**All {checks} checks pass** (informational rows without a check: {}).",
                rows.len() - checks
            );
            return s;
        }
        if !failed.is_empty() {
            let _ = writeln!(s, "**{} of {checks} checks FAIL:**\n", failed.len());
            for r in &failed {
                let _ = writeln!(
                    s,
                    "- {}: ours {}; truth {}; rule: {}",
                    r.metric, r.ours, r.truth, r.rule
                );
            }
            s.push('\n');
        }
        for (k, e) in &studies {
            let _ = writeln!(s, "- **study {k} FAILED:** {e}");
        }
        s
    }

    fn markdown(&self, total: f64, preamble: &str) -> String {
        let mut s = String::from("# T-F-S SINDy paper reproduction\n\n");
        s.push_str(preamble);
        let _ = writeln!(
            s,
            "\nMode: {}; total wall time {:.1} s.\n",
            if self.quick {
                "quick (smaller grids, shorter records)"
            } else {
                "full"
            },
            total
        );
        s.push_str("## Verdict\n\n");
        s.push_str(&self.verdict_text());
        s.push_str("\n## Contents\n\n");
        for (st, err, secs) in &self.studies {
            let _ = writeln!(
                s,
                "- [{}](#{}) — {:.1} s{}",
                st.title,
                st.key,
                secs,
                if err.is_some() { " — **FAILED**" } else { "" }
            );
        }
        s.push_str("\n## Summary\n\n");
        let mut table = self.summary_table();
        for row in &mut table.rows {
            if row[4] == verdict(Some(false)) {
                row[4] = format!("**{}**", row[4]);
            }
        }
        s.push_str(&table.markdown());
        for (st, err, _) in &self.studies {
            let _ = writeln!(s, "\n<a id=\"{}\"></a>\n## {}\n", st.key, st.title);
            if let Some(e) = err {
                let _ = writeln!(s, "**This study failed:** `{e}`\n");
            }
            for b in &st.blocks {
                match b {
                    Block::Text(t) => {
                        s.push_str(t);
                        s.push_str("\n\n");
                    }
                    Block::Table(t) => {
                        s.push_str(&t.markdown());
                        s.push('\n');
                    }
                    Block::Figure { stem, caption } => {
                        let _ = writeln!(
                            s,
                            "![{caption}](figures/{stem}.png)\n\n*{caption}* ([SVG](figures/{stem}.svg))\n"
                        );
                    }
                }
            }
        }
        s
    }

    fn html(&self, total: f64, preamble: &str) -> String {
        let mut s = String::from(
            "<!DOCTYPE html>\n<html><head><meta charset=\"utf-8\"><title>T-F-S SINDy paper reproduction</title>\n<style>body{font-family:sans-serif;max-width:1100px;margin:auto;padding:1em}table{border-collapse:collapse;margin:1em 0}td,th{border:1px solid #bbb;padding:3px 8px;text-align:left}caption{font-weight:bold;text-align:left}img{max-width:100%;border:1px solid #ddd}.fail{color:#b00}tr.fail td{background:#fde2e2;color:#800}tr.pass td:nth-child(5){color:#060}.verdict{border:2px solid #888;padding:0.2em 1em;margin:1em 0}.verdict.bad{border-color:#b00;background:#fff4f4}.verdict.good{border-color:#393;background:#f4fff4}figure{margin:1em 0}code{background:#f4f4f4;padding:0 2px}</style></head><body>\n<h1>T-F-S SINDy paper reproduction</h1>\n",
        );
        s.push_str(&markdown_html(preamble));
        let _ = writeln!(
            s,
            "<p>Mode: {}; total wall time {:.1} s.</p>",
            if self.quick { "quick" } else { "full" },
            total
        );
        let bad = !self.failed_checks().is_empty() || !self.failures().is_empty();
        let _ = writeln!(
            s,
            "<div class=\"verdict {}\"><h2>Verdict</h2>\n{}</div>",
            if bad { "bad" } else { "good" },
            markdown_html(&self.verdict_text())
        );
        s.push_str("<h2>Summary</h2>\n");
        let rows = self.summary();
        s.push_str(&self.summary_table().html_with(|i| {
            rows.get(i).map(|r| match r.within_tolerance {
                Some(false) => "fail",
                Some(true) => "pass",
                None => "info",
            })
        }));
        s.push_str("<ul>\n");
        for (st, err, secs) in &self.studies {
            let _ = writeln!(
                s,
                "<li><a href=\"#{}\">{}</a> ({:.1} s){}</li>",
                st.key,
                esc_html(&st.title),
                secs,
                if err.is_some() {
                    " <span class=\"fail\">FAILED</span>"
                } else {
                    ""
                }
            );
        }
        s.push_str("</ul>\n");
        for (st, err, _) in &self.studies {
            let _ = writeln!(s, "<h2 id=\"{}\">{}</h2>", st.key, esc_html(&st.title));
            if let Some(e) = err {
                let _ = writeln!(
                    s,
                    "<p class=\"fail\">This study failed: <code>{}</code></p>",
                    esc_html(e)
                );
            }
            for b in &st.blocks {
                match b {
                    Block::Text(t) => s.push_str(&markdown_html(t)),
                    Block::Table(t) => s.push_str(&t.html_with(|_| None)),
                    Block::Figure { stem, caption } => {
                        let _ = writeln!(
                            s,
                            "<figure><img src=\"figures/{stem}.png\" alt=\"{c}\"><figcaption>{c} (<a href=\"figures/{stem}.svg\">SVG</a>)</figcaption></figure>",
                            c = esc_html(caption)
                        );
                    }
                }
            }
        }
        s.push_str("</body></html>\n");
        s
    }
}

/// Markdown (the report's paragraphs, lists, emphasis and code spans) as HTML. Raw HTML in the
/// text is escaped, not passed through.
fn markdown_html(text: &str) -> String {
    use pulldown_cmark::{Event, Parser, html};
    let events = Parser::new(text).map(|e| match e {
        Event::Html(h) | Event::InlineHtml(h) => Event::Text(h),
        other => other,
    });
    let mut out = String::new();
    html::push_html(&mut out, events);
    out
}

/// "pass" / "FAIL" / "info".
pub fn verdict(ok: Option<bool>) -> &'static str {
    match ok {
        Some(true) => "pass",
        Some(false) => "FAIL",
        None => "info",
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn report_with(rows: &[(&str, Option<bool>)]) -> (tempfile::TempDir, Report) {
        let dir = tempfile::tempdir().unwrap();
        let mut st = Study::new("s1", "Study one", dir.path());
        st.text("A **bold** claim with `code` and a list:\n\n- one\n- two <b>raw</b>");
        for (m, ok) in rows {
            st.compare(
                m,
                "1.000",
                "1.100 (+10.00%)",
                "1.050 (+5.00%)",
                *ok,
                "within 5%",
            );
        }
        let mut r = Report::new(dir.path(), true);
        r.push(st, None, 1.0);
        (dir, r)
    }

    /// A failed check is named in the verdict of report.md and index.html, its row is marked,
    /// and the Markdown of the text blocks is rendered in HTML (not shown literally).
    #[test]
    fn failed_checks_are_visible_everywhere() {
        let (_d, r) = report_with(&[
            ("coef a", Some(true)),
            ("coef b", Some(false)),
            ("info", None),
        ]);
        assert_eq!(r.failed_checks().len(), 1);
        let md = r.markdown(1.0, "pre");
        assert!(md.contains("**1 of 2 checks FAIL:**"), "{md}");
        assert!(md.contains("- coef b: ours 1.100 (+10.00%); truth 1.000; rule: within 5%"));
        assert!(md.contains("| **FAIL** |"));
        let html = r.html(1.0, "pre");
        assert!(
            html.contains("<tr class=\"fail\"><td>coef b</td>"),
            "{html}"
        );
        assert!(html.contains("verdict bad"));
        assert!(html.contains("<strong>bold</strong>") && html.contains("<code>code</code>"));
        assert!(html.contains("<li>one</li>"));
        assert!(!html.contains("**bold**") && !html.contains("<b>raw</b>"));
        let (_d, ok) = report_with(&[("coef a", Some(true))]);
        assert!(ok.failed_checks().is_empty());
        assert!(ok.markdown(1.0, "").contains("**All 1 checks pass**"));
        assert!(ok.html(1.0, "").contains("verdict good"));
    }
}
