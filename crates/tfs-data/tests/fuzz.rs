//! Fuzzing the CSV reader with proptest (runs in `cargo test`, a bounded number of cases): any
//! bytes give a record or a one-line error naming the file — never a panic — and the reader's
//! work is bounded (an endless line is refused at a fixed length).

use std::io::Read;

use proptest::prelude::*;
use tfs_data::{CsvOptions, CsvTable, DataError, Record, from_reader};

/// A valid record's text with `sep` between cells.
fn good_text(n: usize, sep: &str) -> String {
    let mut s = format!("t{sep}x{sep}xb_acc\n");
    for i in 0..n {
        let t = i as f64 * 0.01;
        s.push_str(&format!(
            "{t}{sep}{}{sep}{}\n",
            (3.0 * t).sin() + 0.1 * t,
            (5.0 * t).cos()
        ));
    }
    s
}

/// Asserts the reader's contract on one input: a record, or a one-line error that names the file.
fn check(bytes: &[u8]) -> Result<Record, DataError> {
    let opts = CsvOptions::default().require(["x"]);
    let r = from_reader("fuzz.csv", bytes, &opts);
    if let Err(e) = &r {
        let m = e.to_string();
        assert!(!m.contains('\n'), "two lines: {m}");
        assert!(m.starts_with("fuzz.csv"), "file not named: {m}");
        if let Some(row) = e.row() {
            let lines = bytes.split(|b| *b == b'\n').count() as u64;
            assert!(
                row <= lines + 1,
                "row {row} past the end ({lines} lines): {m}"
            );
        }
    }
    r
}

/// Pieces that break CSV readers: separators, quotes, line ends, signs, exponents, non-finite
/// spellings, a byte-order mark, non-ASCII and invalid UTF-8.
fn token() -> impl Strategy<Value = Vec<u8>> {
    prop_oneof![
        Just(b",".to_vec()),
        Just(b";".to_vec()),
        Just(b"\t".to_vec()),
        Just(b"\"".to_vec()),
        Just(b"\n".to_vec()),
        Just(b"\r\n".to_vec()),
        Just(b"#".to_vec()),
        Just(b" ".to_vec()),
        Just(b"-".to_vec()),
        Just(b".".to_vec()),
        Just(b"e".to_vec()),
        Just(b"1e309".to_vec()),
        Just(b"1e300".to_vec()),
        Just(b"nan".to_vec()),
        Just(b"inf".to_vec()),
        Just(b"x".to_vec()),
        Just(b"t".to_vec()),
        Just(vec![0xEF, 0xBB, 0xBF]),
        Just("é".as_bytes().to_vec()),
        Just(vec![0xFF, 0xFE]),
        Just(vec![0]),
        "[0-9]{1,4}".prop_map(|s| s.into_bytes()),
    ]
}

/// An edit of a text: insert, delete or replace at a relative position.
fn edit() -> impl Strategy<Value = (u8, f64, Vec<u8>)> {
    (0u8..3, 0.0f64..1.0, token())
}

fn apply(text: &[u8], edits: &[(u8, f64, Vec<u8>)]) -> Vec<u8> {
    let mut v = text.to_vec();
    for (kind, at, tok) in edits {
        let i = ((v.len() as f64) * at) as usize;
        let i = i.min(v.len());
        match kind {
            0 => {
                v.splice(i..i, tok.iter().copied());
            }
            1 => {
                let j = (i + tok.len()).min(v.len());
                v.drain(i..j);
            }
            _ => {
                let j = (i + tok.len()).min(v.len());
                v.splice(i..j, tok.iter().copied());
            }
        }
    }
    v
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(512))]

    /// Arbitrary bytes: a record or a clear error, never a panic.
    #[test]
    fn arbitrary_bytes_never_panic(bytes in proptest::collection::vec(any::<u8>(), 0..600)) {
        let _ = check(&bytes);
    }

    /// A valid file with a few hostile edits: a record or a clear error, never a panic. Edits
    /// that keep the file valid give a record whose columns all have the time axis's length.
    #[test]
    fn edited_files_never_panic(
        n in 16usize..40,
        sep in prop_oneof![Just(","), Just(";"), Just("\t")],
        edits in proptest::collection::vec(edit(), 1..6),
    ) {
        let text = apply(good_text(n, sep).as_bytes(), &edits);
        if let Ok(r) = check(&text) {
            for name in r.names() {
                prop_assert_eq!(r.column(name).unwrap().len(), r.len());
            }
        }
    }

    /// Every separator the reader accepts reads a file back to the same numbers.
    #[test]
    fn separators_read_the_same_numbers(
        n in 16usize..60,
        sep in prop_oneof![Just(","), Just(";"), Just("\t"), Just(" "), Just("  ")],
        crlf in any::<bool>(),
    ) {
        let mut text = good_text(n, sep);
        if crlf {
            text = text.replace('\n', "\r\n");
        }
        let r = check(text.as_bytes()).unwrap();
        let reference = check(good_text(n, ",").as_bytes()).unwrap();
        prop_assert_eq!(r.t(), reference.t());
        prop_assert_eq!(r.column("x"), reference.column("x"));
        prop_assert_eq!(r.column("xb_acc"), reference.column("xb_acc"));
    }
}

/// A reader that never ends and never writes a newline (like /dev/zero).
struct Endless;

impl Read for Endless {
    fn read(&mut self, buf: &mut [u8]) -> std::io::Result<usize> {
        buf.fill(b'0');
        Ok(buf.len())
    }
}

/// An endless line is refused at a fixed length instead of filling the memory.
#[test]
fn endless_line_is_refused() {
    let e = CsvTable::from_reader("zero", Endless).unwrap_err();
    let m = e.to_string();
    assert!(
        m.starts_with("zero: row 1") && m.contains("longer than"),
        "{m}"
    );
    // The same after a valid header: the bad row is named once the header's columns are checked.
    let head = std::io::Cursor::new(b"t,x\n0,1\n".to_vec());
    let e = CsvTable::from_reader("zero", head.chain(Endless))
        .unwrap()
        .into_record(&CsvOptions::default())
        .unwrap_err();
    assert!(
        e.to_string().contains("row 3") && e.to_string().contains("longer than"),
        "{e}"
    );
}

/// A `;`-separated file written with decimal commas gets told to write decimal points.
#[test]
fn decimal_comma_is_named() {
    let text = good_text(20, ";").replacen("0.01;", "0,01;", 1);
    let e = check(text.as_bytes()).unwrap_err().to_string();
    assert!(
        e.contains("\"0,01\"") && e.contains("decimal point (0.01)"),
        "{e}"
    );
}

/// Rows `0.5,1` without end, counting the bytes read.
struct EndlessRows<'a>(&'a std::cell::Cell<u64>);

impl Read for EndlessRows<'_> {
    fn read(&mut self, buf: &mut [u8]) -> std::io::Result<usize> {
        // Stop after 64 MiB so a reader that reads on fails the assertion instead of hanging.
        if self.0.get() > 64 << 20 {
            return Ok(0);
        }
        let row = b"0.5,1\n";
        let n = buf.len() / row.len() * row.len();
        for chunk in buf[..n].chunks_mut(row.len()) {
            chunk.copy_from_slice(row);
        }
        self.0.set(self.0.get() + n as u64);
        Ok(n)
    }
}

/// Endless input whose time stops increasing at row 3 fails there at once: the time column is
/// checked as rows arrive (a stream is not read to its memory limit first).
#[test]
fn endless_rows_with_a_bad_time_stop_at_once() {
    let read = std::cell::Cell::new(0);
    let head = std::io::Cursor::new(b"t,x\n0,1\n0.01,2\n0.005,3\n".to_vec());
    let e = CsvTable::from_reader("stream", head.chain(EndlessRows(&read)))
        .unwrap()
        .into_record(&CsvOptions::default())
        .unwrap_err();
    let m = e.to_string();
    assert!(
        m.contains("row 4") && m.contains("does not increase"),
        "{m}"
    );
    assert!(read.get() < 1 << 20, "{} bytes read", read.get());
    // A column other than `t` as the time axis gets the same.
    let head = std::io::Cursor::new(b"x,time\n1,0\n2,0.01\n3,0.005\n".to_vec());
    let e = CsvTable::from_reader("stream", head.chain(EndlessRows(&read)))
        .unwrap()
        .into_record(&CsvOptions::default().time_column("time"))
        .unwrap_err();
    assert!(e.to_string().contains("column 'time'"), "{e}");
}
