//! Checks of the paths a command writes, made before any work: every output is a file tfs may
//! replace (not a device, FIFO, directory or read-only file), none is one of the command's
//! inputs, no two outputs are the same file, and figures derived from several records get
//! distinct names.

use std::collections::HashSet;
use std::path::{Path, PathBuf};

use anyhow::{Context, Result, bail};

/// Checks every file in `outs` before anything is computed, and creates their folders when
/// missing. `flag` (with `given`, the path the user typed) names the option in messages; an
/// output derived from it (a figure's `.svg` beside `--out X.png`) is named as such.
pub fn check_outputs(given: &Path, outs: &[PathBuf], inputs: &[&Path], flag: &str) -> Result<()> {
    if given.as_os_str() == "-" {
        bail!("{flag} -: write to a file; the result goes to stdout with --json");
    }
    let what = |out: &Path| {
        if out == given {
            format!("{flag} {}", given.display())
        } else {
            format!("{flag} {}: {}", given.display(), out.display())
        }
    };
    let mut seen: Vec<(String, &Path)> = Vec::new();
    for out in outs {
        tfs::data::check_target(out).map_err(|e| anyhow::anyhow!("{}: {e}", what(out)))?;
        let id = tfs::records::file_identity(out);
        if let Some(p) = inputs.iter().find(|p| tfs::records::file_identity(p) == id) {
            bail!(
                "{}: this is also an input ({}); writing there would replace it with the result. Choose another file name",
                what(out),
                p.display()
            );
        }
        if let Some((_, first)) = seen.iter().find(|(s, _)| *s == id) {
            bail!(
                "{}: the same file as {}, which this command writes too; choose another file name",
                what(out),
                first.display()
            );
        }
        seen.push((id, out));
    }
    for out in outs {
        if let Some(dir) = out.parent().filter(|d| !d.as_os_str().is_empty()) {
            std::fs::create_dir_all(dir).with_context(|| {
                format!("{}: cannot create the folder {}", what(out), dir.display())
            })?;
        }
    }
    Ok(())
}

/// The two files a figure saved at `out` is written to (`tfs_plot::Figure::save`): the path
/// without its extension, as `.svg` and `.png`.
pub fn figure_files(out: &Path) -> Vec<PathBuf> {
    let stem = out.with_extension("");
    vec![stem.with_extension("svg"), stem.with_extension("png")]
}

/// Checks a `--plots` folder before any work: it is a folder (or does not exist yet and is
/// created), and no input is a figure inside it (a figure written there could replace it).
pub fn check_plot_dir(dir: &Path, inputs: &[&Path]) -> Result<()> {
    if dir.exists() && !dir.is_dir() {
        bail!(
            "--plots {}: is a file, not a folder; give a folder for the figures",
            dir.display()
        );
    }
    std::fs::create_dir_all(dir)
        .with_context(|| format!("--plots {}: cannot create the folder", dir.display()))?;
    let folder = tfs::records::file_identity(dir);
    for p in inputs {
        let figure = matches!(
            p.extension().and_then(|e| e.to_str()),
            Some("svg" | "png" | "SVG" | "PNG")
        );
        let parent = match p.parent() {
            Some(d) if !d.as_os_str().is_empty() => d,
            _ => Path::new("."),
        };
        if figure && tfs::records::file_identity(parent) == folder {
            bail!(
                "--plots {}: the input {} is a figure in that folder and could be replaced by one; give another folder",
                dir.display(),
                p.display()
            );
        }
    }
    Ok(())
}

/// Figure names for records, one per path: the file's stem, made distinct when two records share
/// one (`a/rec.csv` and `b/rec.csv` become `a-rec` and `b-rec`; `rec-2` … when the folders are
/// named alike too). Standard input (`-`) is `stdin`.
pub fn record_figure_names(paths: &[PathBuf]) -> Vec<String> {
    let stem = |p: &Path| -> String {
        if p.as_os_str() == "-" {
            return "stdin".into();
        }
        p.file_stem()
            .and_then(|s| s.to_str())
            .filter(|s| !s.is_empty())
            .unwrap_or("record")
            .to_string()
    };
    let stems: Vec<String> = paths.iter().map(|p| stem(p)).collect();
    let shared = |s: &String| stems.iter().filter(|t| *t == s).count() > 1;
    let mut used: HashSet<String> = stems.iter().filter(|s| !shared(s)).cloned().collect();
    let mut names = Vec::with_capacity(paths.len());
    for (p, s) in paths.iter().zip(&stems) {
        if !shared(s) {
            names.push(s.clone());
            continue;
        }
        let folder = p
            .parent()
            .and_then(|d| d.file_name())
            .and_then(|d| d.to_str())
            .map(|d| format!("{d}-{s}"));
        let name = match folder {
            Some(n) if !used.contains(&n) => n,
            _ => (2..)
                .map(|k| format!("{s}-{k}"))
                .find(|n| !used.contains(n))
                .unwrap_or_else(|| s.clone()),
        };
        used.insert(name.clone());
        names.push(name);
    }
    names
}

/// For `diagnose`/`refit --plots DIR`: [`check_plot_dir`] with the model, the records and the
/// model file written (`out`) as the files that must not be replaced.
pub fn check_plots_for(
    dir: &Path,
    model: &Path,
    records: &[PathBuf],
    out: Option<&Path>,
) -> Result<()> {
    let files: Vec<&Path> = std::iter::once(model)
        .chain(records.iter().map(PathBuf::as_path))
        .chain(out)
        .collect();
    check_plot_dir(dir, &files)
}

/// For `compare --plots DIR`: checks the folder and every figure (`NAME-DOF.svg`/`.png`, one
/// name per record from [`record_figure_names`]) against the model and the records, before any
/// work; returns the names.
pub fn record_figures(
    dir: &Path,
    model: &Path,
    records: &[PathBuf],
    dofs: &[String],
) -> Result<Vec<String>> {
    let inputs: Vec<&Path> = std::iter::once(model)
        .chain(records.iter().map(PathBuf::as_path))
        .collect();
    check_plot_dir(dir, &inputs)?;
    let names = record_figure_names(records);
    let outs: Vec<PathBuf> = names
        .iter()
        .flat_map(|n| dofs.iter().map(move |d| dir.join(format!("{n}-{d}"))))
        .flat_map(|stem| figure_files(&stem))
        .collect();
    check_outputs(dir, &outs, &inputs, "--plots")?;
    Ok(names)
}

/// The files `simulate --out OUT` writes for `n` records: `OUT` itself for one record, else
/// `OUT` with `-1`, `-2`, … before the extension; and the metadata `OUT` with `.meta.json`.
pub fn simulate_outputs(out: &Path, n: usize) -> (Vec<PathBuf>, PathBuf) {
    let csvs = if n == 1 {
        vec![out.to_path_buf()]
    } else {
        let stem = out.with_extension("");
        let ext = out.extension().and_then(|e| e.to_str()).unwrap_or("csv");
        (1..=n)
            .map(|k| PathBuf::from(format!("{}-{k}.{ext}", stem.display())))
            .collect()
    };
    (csvs, out.with_extension("meta.json"))
}

/// Writes `simulate`'s records and metadata as one set: every file is complete before any
/// replaces its previous version, so a failure part-way leaves the previous set whole. Returns
/// the CSV files written.
pub fn write_record_set(
    out: &Path,
    records: &[tfs::data::Record],
    meta: &impl serde::Serialize,
) -> Result<Vec<String>> {
    let (csvs, meta_path) = simulate_outputs(out, records.len());
    let mut set = tfs::data::AtomicSet::new();
    for (path, rec) in csvs.iter().zip(records) {
        tfs::data::write_csv_into(&mut set, path, rec)?;
    }
    let text = serde_json::to_string_pretty(meta)?;
    set.add_with(&meta_path, |w| w.write_all(text.as_bytes()))
        .with_context(|| format!("writing {}", meta_path.display()))?;
    set.commit()
        .with_context(|| format!("--out {}: replacing the files", out.display()))?;
    Ok(csvs.iter().map(|p| p.display().to_string()).collect())
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn figure_names_are_distinct() {
        let p = |s: &str| PathBuf::from(s);
        assert_eq!(
            record_figure_names(&[p("a/rec.csv"), p("b/rec.csv"), p("c.csv")]),
            ["a-rec", "b-rec", "c"]
        );
        let names = record_figure_names(&[p("rec.csv"), p("rec.csv"), p("rec-2.csv")]);
        let set: HashSet<_> = names.iter().collect();
        assert_eq!(set.len(), 3, "{names:?}");
        assert_eq!(names[2], "rec-2");
    }
}
