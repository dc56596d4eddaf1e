//! Which columns of a record `identify` uses, and a note naming the ones it leaves out and why:
//! a rig's input column whose header carries units or a dash (`acc [m/s2]`, `base-acc`) is not
//! one of the input names taken by default and used to be dropped without a word.

/// The note for the columns of `file` (time column excluded) that neither the DOFs nor the
/// libraries use (`required`), leaving out those that are not measurements to fit on: a DOF's
/// velocity or acceleration (`x'`, `x_vel`, `x_acc`, `xdot`, `x_dot`) and simulated truth
/// columns (`*_clean`). `library_given` says whether `--library` chose the terms. `None` when
/// every column is used.
pub fn unused_columns_note(
    file: &str,
    columns: &[String],
    dofs: &[String],
    required: &[String],
    library_given: bool,
) -> Option<String> {
    let derived = |c: &str| {
        c.ends_with("_clean")
            || dofs.iter().any(|d| {
                ["'", "_vel", "_acc", "dot", "_dot"]
                    .iter()
                    .any(|s| c.strip_suffix(s) == Some(d.as_str()))
            })
    };
    let unused: Vec<&String> = columns
        .iter()
        .filter(|c| !required.contains(c) && !derived(c))
        .collect();
    if unused.is_empty() {
        return None;
    }
    let list = unused
        .iter()
        .map(|c| format!("'{c}'"))
        .collect::<Vec<_>>()
        .join(", ");
    let example = tfs::library::quote_name(unused[0]).into_owned();
    let why = if library_given {
        "--library does not name them".to_string()
    } else {
        format!(
            "the default library takes inputs only by the names {}",
            tfs::diagnose::effects::CONTRACT_INPUTS.join(", ")
        )
    };
    let d = &dofs[0];
    Some(format!(
        "{file}: column{} {list} not used ({why}); to fit on one as an input, name it in --library, in double quotes when it has spaces or signs (e.g. --library \"{d}^1..7, {d}', {}\"), or rename it",
        if unused.len() == 1 { "" } else { "s" },
        example.replace('"', "\\\"")
    ))
}

/// Reads the records a model is used on (`compare`, `diagnose`, `refit`): like
/// [`super::read_records`] with the model's measured columns required, but a column the model
/// needs and a file lacks is reported as the model's: its DOF, or the input one of its terms
/// reads (an unknown term such as `foo` is read by the grammar as an input column `foo`).
pub fn read_model_records(
    paths: &[std::path::PathBuf],
    model_path: &std::path::Path,
    model: &tfs::library::Model,
    required: &[String],
    data: &super::DataArgs,
) -> anyhow::Result<Vec<tfs::data::Record>> {
    let tables = tfs::records::read_tables(paths)?;
    for table in &tables {
        let names = table.names();
        let Some(missing) = required.iter().find(|c| !names.contains(c)) else {
            continue;
        };
        let columns = names.join(", ");
        let (file, m) = (table.source(), model_path.display());
        if model.dofs.contains(missing) {
            anyhow::bail!(
                "{file}: the model {m} has the DOF '{missing}', which is not a column of this file (its columns: {columns}); give records with that displacement column, or use a model fitted on these columns"
            );
        }
        let terms: Vec<String> = model
            .equations
            .iter()
            .flat_map(|e| e.terms.iter())
            .map(|t| t.term.to_string())
            .filter(|t| t.contains(missing.as_str()))
            .collect();
        anyhow::bail!(
            "{file}: the model {m} reads an input column '{missing}' (term{} {}), which this file does not have (its columns: {columns}); rename the column, or if '{missing}' is not meant to be a column, correct the model's term",
            if terms.len() == 1 { "" } else { "s" },
            terms.join(", ")
        );
    }
    super::records_from(tables, required, data)
}

/// The fewest rows `identify` fits on per record; a single record is split into two halves
/// (one held out to choose the settings), so it needs twice as many.
pub const MIN_IDENTIFY_ROWS: usize = 64;

/// Refuses records too short for `identify`, naming the file the user gave (the criteria would
/// name an internal half such as `r.csv#1`).
pub fn check_identify_rows(records: &[tfs::data::Record]) -> anyhow::Result<()> {
    if let [one] = records
        && one.len() < 2 * MIN_IDENTIFY_ROWS
    {
        anyhow::bail!(
            "{}: {} data rows; identify holds out half of a single record to choose its settings and fits on at least {MIN_IDENTIFY_ROWS} rows, so one record needs at least {}: record a longer stretch, or give a second record",
            one.source(),
            one.len(),
            2 * MIN_IDENTIFY_ROWS
        );
    }
    if let Some(r) = records.iter().find(|r| r.len() < MIN_IDENTIFY_ROWS) {
        anyhow::bail!(
            "{}: {} data rows; identify needs at least {MIN_IDENTIFY_ROWS} from each record: record a longer stretch or leave this one out",
            r.source(),
            r.len()
        );
    }
    Ok(())
}

/// Refuses a repeatable flag given the same value twice (`--add E --add E`), which would
/// otherwise be taken for a request the second time cannot honour.
pub fn refuse_repeated(flag: &str, values: &[String]) -> anyhow::Result<()> {
    for (i, v) in values.iter().enumerate() {
        if values[..i].contains(v) {
            anyhow::bail!("{flag} {v} is given twice; name each once");
        }
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn names_what_is_left_out() {
        let s = |v: &[&str]| v.iter().map(|c| c.to_string()).collect::<Vec<_>>();
        let cols = s(&["x", "acc [m/s2]", "x'", "x_clean", "xb_acc"]);
        let note =
            unused_columns_note("r.csv", &cols, &s(&["x"]), &s(&["x", "xb_acc"]), false).unwrap();
        assert!(note.contains("column 'acc [m/s2]' not used"), "{note}");
        assert!(note.contains(r#"\"acc [m/s2]\""#), "{note}");
        assert!(
            !note.contains("x_clean") && !note.contains("'x''"),
            "{note}"
        );
        assert!(unused_columns_note("r.csv", &cols[..1], &s(&["x"]), &s(&["x"]), false).is_none());
    }
}
