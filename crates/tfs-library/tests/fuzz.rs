//! Fuzzing the term grammar and the model-file reader with proptest (runs in `cargo test`, a
//! bounded number of cases): any text gives a library, a term or a model — or a one-line error
//! that says where and what — never a panic, and no spec expands past a fixed number of terms.

use proptest::prelude::*;
use tfs_library::{Library, LibraryError, MAX_SPEC_TERMS, Model, Term};

const DOFS: [&str; 2] = ["x1", "x2"];

/// Pieces of the grammar and things that break it.
fn token() -> impl Strategy<Value = String> {
    prop_oneof![
        prop::sample::select(vec![
            "x1",
            "x2",
            "xb_acc",
            "u",
            "'",
            "^",
            "..",
            ",",
            ";",
            "*",
            "(",
            ")",
            "-",
            "/",
            "1",
            "0",
            "abs",
            "sign",
            "tanh",
            "below",
            "above",
            "poly",
            "nan",
            "inf",
            "-0.5",
            "1e400",
            " ",
            "é",
            "∞",
            "x1^",
            "(x2-x1)",
            "4294967296",
            "99999",
        ])
        .prop_map(String::from),
        "[0-9]{1,6}",
        "[a-z_]{1,4}",
    ]
}

fn spec() -> impl Strategy<Value = String> {
    prop::collection::vec(token(), 0..24).prop_map(|v| v.concat())
}

/// A parse error must point inside (or just past) the text and be one line.
fn check_error(text: &str, e: &LibraryError) {
    let m = e.to_string();
    assert!(!m.contains('\n'), "two lines: {m}");
    if let LibraryError::Parse { position, .. } = e {
        assert!(
            *position <= text.chars().count(),
            "position {position} past the end of {text:?}"
        );
    }
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(1024))]

    /// Token soup: a library of at most MAX_SPEC_TERMS distinct terms, or a clear error.
    #[test]
    fn specs_never_panic(text in spec()) {
        match Library::parse(&text, &DOFS) {
            Ok(lib) => {
                prop_assert!(lib.len() <= MAX_SPEC_TERMS);
                // What parses prints back to a spec that parses to the same library.
                let again = Library::parse(&lib.spec(), &DOFS);
                if !lib.is_empty() {
                    prop_assert_eq!(again.unwrap(), lib);
                }
            }
            Err(e) => check_error(&text, &e),
        }
        match Term::parse(&text, &DOFS) {
            Ok(t) => prop_assert_eq!(Term::parse(&t.to_string(), &DOFS).unwrap(), t),
            Err(e) => check_error(&text, &e),
        }
    }

    /// Arbitrary Unicode: never a panic.
    #[test]
    fn arbitrary_text_never_panics(text in "\\PC{0,80}") {
        if let Err(e) = Library::parse(&text, &DOFS) {
            check_error(&text, &e);
        }
    }

    /// Ranges, products of ranges and `poly` that would expand past the limit are refused
    /// before anything is built (this runs in microseconds, whatever the numbers).
    #[test]
    fn huge_expansions_are_refused(hi in 70u32..4_000_000_000, k in 2usize..5) {
        let cases = [
            format!("x1^1..{hi}"),
            format!("x1^0..{hi}"),
            vec!["x1^1..70"; k].join("*"),
            format!("poly(x1, x2, x1', x2'; 0..{})", hi.min(1024)),
        ];
        for c in &cases {
            let t = std::time::Instant::now();
            let r = Library::parse(c, &DOFS);
            prop_assert!(t.elapsed().as_secs_f64() < 1.0, "{} took {:?}", c, t.elapsed());
            match r {
                Ok(lib) => prop_assert!(lib.len() <= MAX_SPEC_TERMS, "{}", c),
                Err(e) => {
                    let m = e.to_string();
                    prop_assert!(m.contains("at most"), "{}: {}", c, m);
                }
            }
        }
    }
}

/// A valid tfs-model/1 file.
fn model_json() -> String {
    r#"{"format":"tfs-model/1","dofs":["x"],"inputs":["xb_acc"],
"equations":[{"dof":"x","terms":[{"term":"x'","coef":-1.99,"interval":[-2.1,-1.9]},
{"term":"x^5","coef":-12.12},{"term":"x^6","coef":18.03},{"term":"xb_acc","coef":-1.0}]}],
"method":"tfs","trace":{"note":"a"},"history":[]}"#
        .to_string()
}

fn json_token() -> impl Strategy<Value = String> {
    prop_oneof![
        prop::sample::select(vec![
            "{",
            "}",
            "[",
            "]",
            ",",
            ":",
            "\"",
            "null",
            "true",
            "1e999",
            "-0",
            "NaN",
            "\"x\"",
            "\"x^2\"",
            "\"term\"",
            "\"coef\"",
            "\"dofs\"",
            "\"equations\"",
            "\"x''\"",
            "\\u0000",
            "\"tfs-model/2\"",
            "é",
        ])
        .prop_map(String::from),
        "[0-9]{1,5}",
    ]
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(1024))]

    /// A model file with a few hostile edits: a valid model or a one-line error, never a panic.
    #[test]
    fn edited_model_files_never_panic(
        edits in prop::collection::vec((0u8..3, 0.0f64..1.0, json_token()), 1..5)
    ) {
        let mut text: Vec<char> = model_json().chars().collect();
        for (kind, at, tok) in &edits {
            let i = ((text.len() as f64 * at) as usize).min(text.len());
            let tok: Vec<char> = tok.chars().collect();
            let j = (i + tok.len()).min(text.len());
            match kind {
                0 => { text.splice(i..i, tok); }
                1 => { text.drain(i..j); }
                _ => { text.splice(i..j, tok); }
            }
        }
        let text: String = text.into_iter().collect();
        match Model::from_json_str(&text) {
            Ok(m) => {
                prop_assert!(m.equations.iter().any(|e| !e.terms.is_empty()));
                prop_assert!(m.validate().is_ok());
            }
            Err(e) => prop_assert!(!e.to_string().contains('\n'), "{}", e),
        }
    }

    /// Random term names and coefficients in a well-formed file: never a panic.
    #[test]
    fn random_terms_never_panic(
        terms in prop::collection::vec((spec(), any::<f64>()), 0..5)
    ) {
        let list: Vec<String> = terms
            .iter()
            .map(|(t, c)| {
                let c = if c.is_finite() { c.to_string() } else { "1e999".into() };
                format!(r#"{{"term":{},"coef":{c}}}"#, serde_json::to_string(t).unwrap())
            })
            .collect();
        let text = format!(
            r#"{{"format":"tfs-model/1","dofs":["x1","x2"],"equations":[{{"dof":"x1","terms":[{}]}},{{"dof":"x2","terms":[]}}]}}"#,
            list.join(",")
        );
        if let Err(e) = Model::from_json_str(&text) {
            prop_assert!(!e.to_string().contains('\n'), "{}", e);
        }
    }
}

/// A term listed twice in one equation is refused by name (it was summed silently: a model
/// file whose basin then had one stable state instead of two).
#[test]
fn duplicate_term_is_refused() {
    let text = model_json().replace(r#""term":"x^6""#, r#""term":"x*x^4""#);
    // x*x^4 is x^5 written another way.
    let e = Model::from_json_str(&text).unwrap_err().to_string();
    assert!(
        e.contains("'x^5'") && e.contains("twice") && e.contains("terms[1]"),
        "{e}"
    );
}

/// A model with no term at all predicts nothing: refused with what to do.
#[test]
fn model_without_terms_is_refused() {
    let text = r#"{"format":"tfs-model/1","dofs":["x"],"equations":[{"dof":"x","terms":[]}]}"#;
    let e = Model::from_json_str(text).unwrap_err().to_string();
    assert!(e.contains("no terms"), "{e}");
}

/// Files that are not model files: binary, too large, empty.
#[test]
fn corrupt_model_files_get_a_clear_error() {
    let dir = tempfile::tempdir().unwrap();
    let bin = dir.path().join("m.json");
    std::fs::write(&bin, [0xFFu8, 0xD8, 0xFF, 0xE0, 0, 1, 2]).unwrap();
    let e = Model::from_path(&bin).unwrap_err().to_string();
    assert!(
        e.contains("m.json") && e.contains("not a model file"),
        "{e}"
    );
    std::fs::write(&bin, "").unwrap();
    let e = Model::from_path(&bin).unwrap_err().to_string();
    assert!(
        e.contains("m.json") && e.contains("invalid model JSON"),
        "{e}"
    );
    let trunc = &model_json()[..60];
    std::fs::write(&bin, trunc).unwrap();
    let e = Model::from_path(&bin).unwrap_err().to_string();
    assert!(e.contains("line") && e.contains("column"), "{e}");
}

/// An out-of-place number in a stop gets an error that allows a negative position.
#[test]
fn stop_position_error_allows_negative_positions() {
    let e = Library::parse("below(x1, nan)", &DOFS)
        .unwrap_err()
        .to_string();
    assert!(
        !e.contains("positive") && e.contains("-0.12") && e.contains("below(v, c)"),
        "{e}"
    );
    assert!(Library::parse("below(x1, -0.12)", &DOFS).is_ok());
}
