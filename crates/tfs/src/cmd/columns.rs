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
