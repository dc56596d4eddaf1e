//! Recursive-descent parser for term names and library specs.
//!
//! Grammar (whitespace allowed between tokens):
//! ```text
//! spec    := item ("," item)*
//! item    := "poly" "(" var ("," var)* ";" int ".." int ")" | product
//! product := factor ("*" factor)*
//! factor  := "1" | ("abs" | "sign") "(" var ")" | "tanh" "(" var "/" number ")"
//!          | ("below" | "above") "(" var "," signed ")"
//!          | "maxwell" "(" var "," number ")" | "dahl" "(" var "," number ")"
//!          | "bouc_wen" "(" var "," signed "," signed ["," number] ")"
//!          | var ["^" int [".." int]]
//! var     := ident ["'"] | "(" ident "-" ident ")" ["'"]
//! ```

use crate::state::StateLaw;
use crate::term::{Coord, Factor, Term, Var};
use crate::{LibraryError, Result};

/// One parsed factor slot: the alternatives a range expands to (`None` = power 0, i.e. `1`).
type Choices = Vec<Option<Factor>>;

/// The most terms a library spec may expand to (ranges, products of ranges and `poly` counted
/// before anything is built): every candidate is a matrix column over every sample, and sparse
/// regression needs far more independent samples than candidates.
pub const MAX_SPEC_TERMS: usize = 4096;

/// The highest power a term may have: beyond it every value other than ±1 and 0 under- or
/// overflows a double.
pub const MAX_POWER: u32 = 1024;

struct Parser<'a> {
    text: &'a str,
    chars: Vec<char>,
    pos: usize,
    dofs: &'a [&'a str],
    allow_ranges: bool,
}

impl<'a> Parser<'a> {
    fn new(text: &'a str, dofs: &'a [&'a str], allow_ranges: bool) -> Self {
        Self {
            text,
            chars: text.chars().collect(),
            pos: 0,
            dofs,
            allow_ranges,
        }
    }

    fn skip_ws(&mut self) {
        while self.pos < self.chars.len() && self.chars[self.pos].is_whitespace() {
            self.pos += 1;
        }
    }

    fn peek(&mut self) -> Option<char> {
        self.skip_ws();
        self.chars.get(self.pos).copied()
    }

    fn found(&self) -> String {
        match self.chars.get(self.pos) {
            None => "end of input".to_string(),
            Some(c) if c.is_alphanumeric() || *c == '_' => {
                let tok: String = self.chars[self.pos..]
                    .iter()
                    .take_while(|c| c.is_alphanumeric() || **c == '_' || **c == '.')
                    .collect();
                format!("'{tok}'")
            }
            Some(c) => format!("'{c}'"),
        }
    }

    fn err(&self, expected: impl Into<String>) -> LibraryError {
        LibraryError::Parse {
            input: self.text.to_string(),
            position: self.pos,
            found: self.found(),
            expected: expected.into(),
        }
    }

    fn err_at(&self, pos: usize, found: String, expected: impl Into<String>) -> LibraryError {
        LibraryError::Parse {
            input: self.text.to_string(),
            position: pos,
            found,
            expected: expected.into(),
        }
    }

    fn eat(&mut self, c: char) -> bool {
        if self.peek() == Some(c) {
            self.pos += 1;
            true
        } else {
            false
        }
    }

    fn expect(&mut self, c: char, what: &str) -> Result<()> {
        if self.eat(c) {
            Ok(())
        } else {
            Err(self.err(what))
        }
    }

    fn at_end(&mut self) -> bool {
        self.peek().is_none()
    }

    fn ident(&mut self) -> Option<String> {
        self.skip_ws();
        let start = self.pos;
        match self.chars.get(self.pos) {
            Some(c) if c.is_alphabetic() || *c == '_' => {}
            _ => return None,
        }
        while self.pos < self.chars.len()
            && (self.chars[self.pos].is_alphanumeric() || self.chars[self.pos] == '_')
        {
            self.pos += 1;
        }
        Some(self.chars[start..self.pos].iter().collect())
    }

    /// A column name: an identifier, or any text in double quotes (`"acc [m/s2]"`, `"base-acc"`;
    /// `""` for a quote inside), so that a header with units or dashes can be named.
    fn column_name(&mut self) -> Result<Option<String>> {
        self.skip_ws();
        if self.chars.get(self.pos) != Some(&'"') {
            return Ok(self.ident());
        }
        let start = self.pos;
        self.pos += 1;
        let mut name = String::new();
        loop {
            match self.chars.get(self.pos) {
                None => {
                    return Err(self.err_at(
                        start,
                        "'\"' that is not closed".into(),
                        "a closing '\"' after a quoted column name",
                    ));
                }
                Some('"') if self.chars.get(self.pos + 1) == Some(&'"') => {
                    name.push('"');
                    self.pos += 2;
                }
                Some('"') => {
                    self.pos += 1;
                    break;
                }
                Some(c) => {
                    name.push(*c);
                    self.pos += 1;
                }
            }
        }
        if name.trim().is_empty() {
            return Err(self.err_at(start, "'\"\"'".into(), "a column name inside the quotes"));
        }
        Ok(Some(name))
    }

    fn uint(&mut self, what: &str) -> Result<u32> {
        self.skip_ws();
        let start = self.pos;
        while self.pos < self.chars.len() && self.chars[self.pos].is_ascii_digit() {
            self.pos += 1;
        }
        if start == self.pos {
            return Err(self.err(what));
        }
        let s: String = self.chars[start..self.pos].iter().collect();
        s.parse::<u32>()
            .map_err(|_| self.err_at(start, format!("'{s}'"), "an integer that fits in 32 bits"))
    }

    fn number(&mut self, expected: &str) -> Result<f64> {
        self.skip_ws();
        let start = self.pos;
        let digits = |p: &mut Self| {
            let s = p.pos;
            while p.pos < p.chars.len() && p.chars[p.pos].is_ascii_digit() {
                p.pos += 1;
            }
            p.pos > s
        };
        let mut any = digits(self);
        if self.chars.get(self.pos) == Some(&'.') {
            self.pos += 1;
            any |= digits(self);
        }
        if !any {
            self.pos = start;
            return Err(self.err(expected));
        }
        if matches!(self.chars.get(self.pos), Some('e' | 'E')) {
            let save = self.pos;
            self.pos += 1;
            if matches!(self.chars.get(self.pos), Some('+' | '-')) {
                self.pos += 1;
            }
            if !digits(self) {
                self.pos = save;
            }
        }
        let s: String = self.chars[start..self.pos].iter().collect();
        s.parse::<f64>()
            .map_err(|_| self.err_at(start, format!("'{s}'"), expected))
    }

    fn is_dof(&self, name: &str) -> bool {
        self.dofs.contains(&name)
    }

    /// var := name ["'"] | "(" name "-" name ")" ["'"], a name being an identifier or quoted text
    fn var(&mut self) -> Result<Var> {
        self.skip_ws();
        let start = self.pos;
        if self.eat('(') {
            let a_pos = {
                self.skip_ws();
                self.pos
            };
            let a = self
                .column_name()?
                .ok_or_else(|| self.err("a DOF name after '(' in a relative coordinate (a-b)"))?;
            if !self.is_dof(&a) {
                return Err(self.err_at(
                    a_pos,
                    format!("'{a}'"),
                    format!(
                        "a DOF name (one of {:?}) as the first operand of a relative coordinate",
                        self.dofs
                    ),
                ));
            }
            self.expect('-', "'-' in a relative coordinate (a-b)")?;
            let b_pos = {
                self.skip_ws();
                self.pos
            };
            let b = self
                .column_name()?
                .ok_or_else(|| self.err("a DOF or input name after '-' in (a-b)"))?;
            if a == b {
                return Err(self.err_at(
                    b_pos,
                    format!("'{b}'"),
                    "a coordinate different from the first operand of (a-b)",
                ));
            }
            self.expect(')', "')' closing the relative coordinate")?;
            let b = if self.is_dof(&b) {
                Coord::Dof(b)
            } else {
                Coord::Input(b)
            };
            if self.chars.get(self.pos) == Some(&'\'') {
                self.pos += 1;
                return Ok(Var::RelVel(a, b));
            }
            return Ok(Var::RelDisp(a, b));
        }
        let name = self.column_name()?.ok_or_else(|| {
            self.err("a variable: a DOF, a DOF velocity like x', (x2-x1), or an input column (quoted when its name has other characters: \"acc [m/s2]\")")
        })?;
        if self.chars.get(self.pos) == Some(&'\'') {
            if !self.is_dof(&name) {
                return Err(self.err_at(
                    start,
                    format!("'{name}''"),
                    format!(
                        "the velocity of a DOF (one of {:?}); '{name}' is an input, use its velocity column '{name}_vel' instead",
                        self.dofs
                    ),
                ));
            }
            self.pos += 1;
            return Ok(Var::Vel(name));
        }
        if self.is_dof(&name) {
            Ok(Var::Disp(name))
        } else {
            Ok(Var::Input(name))
        }
    }

    /// Looks ahead: is the next identifier `name` followed by `(`?
    fn at_call(&mut self, name: &str) -> bool {
        self.skip_ws();
        let save = self.pos;
        let ok = self.ident().as_deref() == Some(name) && self.peek() == Some('(');
        self.pos = save;
        ok
    }

    fn factor(&mut self) -> Result<Choices> {
        self.skip_ws();
        let start = self.pos;
        if self.chars.get(self.pos) == Some(&'1')
            && !self
                .chars
                .get(self.pos + 1)
                .is_some_and(|c| c.is_ascii_digit() || *c == '.')
        {
            self.pos += 1;
            return Ok(vec![None]);
        }
        for func in ["below", "above"] {
            if self.at_call(func) {
                self.ident();
                self.expect('(', "'('")?;
                let v = self.var()?;
                self.expect(',', &format!("',' and the stop's position: {func}(v, c)"))?;
                self.skip_ws();
                let negative = self.eat('-');
                let npos = self.pos;
                let c = self.number(&format!(
                    "the stop's position, a finite number such as 0.5 or -0.12, in {func}(v, c)"
                ))?;
                if !c.is_finite() {
                    return Err(self.err_at(
                        npos,
                        format!("'{c}'"),
                        format!("a finite position c in {func}(v, c)"),
                    ));
                }
                let c = if negative { -c } else { c };
                self.expect(')', &format!("')' closing {func}("))?;
                let f = if func == "below" {
                    Factor::Below(v, c)
                } else {
                    Factor::Above(v, c)
                };
                return Ok(vec![Some(f)]);
            }
        }
        for func in ["maxwell", "bouc_wen", "dahl"] {
            if self.at_call(func) {
                return Ok(vec![Some(self.state_factor(func, start)?)]);
            }
        }
        for func in ["abs", "sign", "tanh"] {
            if self.at_call(func) {
                self.ident();
                self.expect('(', "'('")?;
                let v = self.var()?;
                let f = match func {
                    "abs" => Factor::Abs(v),
                    "sign" => Factor::Sign(v),
                    _ => {
                        self.expect('/', "'/' and a smoothing width: tanh(v/eps)")?;
                        let npos = self.pos;
                        let eps =
                            self.number("a positive smoothing width such as 0.01 in tanh(v/eps)")?;
                        if !(eps > 0.0 && eps.is_finite()) {
                            return Err(self.err_at(
                                npos,
                                format!("'{eps}'"),
                                "a positive finite smoothing width eps in tanh(v/eps)",
                            ));
                        }
                        Factor::Tanh(v, eps)
                    }
                };
                self.expect(')', &format!("')' closing {func}("))?;
                return Ok(vec![Some(f)]);
            }
        }
        if self.at_call("poly") {
            return Err(self.err_at(
                start,
                "'poly'".into(),
                "poly(...) as a whole list item, not inside a product",
            ));
        }
        let v = self.var()?;
        if !self.eat('^') {
            return Ok(vec![Some(Factor::Pow(v, 1))]);
        }
        let kpos = {
            self.skip_ws();
            self.pos
        };
        let lo = self.uint("an integer power after '^'")?;
        if lo > MAX_POWER {
            return Err(self.err_at(
                kpos,
                format!("'{lo}'"),
                format!("a power of at most {MAX_POWER}"),
            ));
        }
        let hi = if self.peek() == Some('.') && self.chars.get(self.pos + 1) == Some(&'.') {
            if !self.allow_ranges {
                return Err(
                    self.err("a single term; ranges like ^1..7 are only allowed in library specs")
                );
            }
            self.pos += 2;
            let hpos = {
                self.skip_ws();
                self.pos
            };
            let hi = self.uint("an integer upper bound after '..'")?;
            if hi < lo {
                return Err(self.err_at(
                    hpos,
                    format!("'{hi}'"),
                    format!("an upper bound not below the lower bound {lo}"),
                ));
            }
            if hi > MAX_POWER {
                return Err(self.err_at(
                    hpos,
                    format!("'{hi}'"),
                    format!("a power of at most {MAX_POWER}"),
                ));
            }
            hi
        } else {
            if lo == 0 {
                return Err(self.err_at(
                    kpos,
                    "'0'".into(),
                    "a power of at least 1 (write 1 for the constant)",
                ));
            }
            lo
        };
        Ok((lo..=hi)
            .map(|k| (k > 0).then(|| Factor::Pow(v.clone(), k)))
            .collect())
    }

    /// A number with an optional leading '-'.
    fn signed(&mut self) -> Result<f64> {
        self.skip_ws();
        let negative = self.eat('-');
        let v = self.number("a number such as 0.5 or -1.1 for the state's parameter")?;
        Ok(if negative { -v } else { v })
    }

    /// `maxwell(v, τ)`, `bouc_wen(v, a, b[, ν])` or `dahl(v, κ)` after its name was seen.
    fn state_factor(&mut self, func: &str, start: usize) -> Result<Factor> {
        self.ident();
        self.expect('(', "'('")?;
        let vpos = {
            self.skip_ws();
            self.pos
        };
        let v = self.var()?;
        if !v.is_velocity() {
            return Err(self.err_at(
                vpos,
                format!("'{v}'"),
                format!("a velocity coordinate such as x' or (x2-x1)' driving {func}(...)"),
            ));
        }
        let usage = match func {
            "maxwell" => "maxwell(v', tau)",
            "dahl" => "dahl(v', kappa)",
            _ => "bouc_wen(v', a, b) or bouc_wen(v', a, b, nu)",
        };
        let mut params = Vec::new();
        while self.eat(',') {
            params.push(self.signed()?);
        }
        self.expect(')', &format!("',' and a number, or ')' closing {usage}"))?;
        let law = match (func, params.as_slice()) {
            ("maxwell", [tau]) => StateLaw::Maxwell { tau: *tau },
            ("dahl", [kappa]) => StateLaw::Dahl { kappa: *kappa },
            ("bouc_wen", [a, b]) => StateLaw::BoucWen {
                a: *a,
                b: *b,
                nu: 1.0,
            },
            ("bouc_wen", [a, b, nu]) => StateLaw::BoucWen {
                a: *a,
                b: *b,
                nu: *nu,
            },
            _ => {
                return Err(self.err_at(
                    start,
                    format!("{} parameter(s)", params.len()),
                    usage.to_string(),
                ));
            }
        };
        law.validate().map_err(|e| {
            self.err_at(
                start,
                format!("'{func}'"),
                format!("valid parameters in {usage}: {e}"),
            )
        })?;
        Ok(Factor::State(v, law))
    }

    fn product(&mut self, budget: usize) -> Result<Vec<Term>> {
        let start = {
            self.skip_ws();
            self.pos
        };
        let mut slots = vec![self.factor()?];
        while self.eat('*') {
            slots.push(self.factor()?);
        }
        // Count before expanding: a product of ranges multiplies their lengths.
        let count = slots
            .iter()
            .try_fold(1usize, |acc, s| acc.checked_mul(s.len()))
            .filter(|&c| c <= budget);
        if count.is_none() {
            return Err(self.too_many(start));
        }
        // Cartesian product of the slots' alternatives.
        let mut terms: Vec<Vec<Factor>> = vec![vec![]];
        for slot in slots {
            let mut next = Vec::with_capacity(terms.len() * slot.len());
            for t in &terms {
                for c in &slot {
                    let mut t = t.clone();
                    if let Some(f) = c {
                        t.push(f.clone());
                    }
                    next.push(t);
                }
            }
            terms = next;
        }
        Ok(terms.into_iter().map(Term::new).collect())
    }

    /// The error for a spec that expands past [`MAX_SPEC_TERMS`], at the item that does it.
    fn too_many(&self, pos: usize) -> LibraryError {
        let item: String = self.chars[pos..self.pos].iter().collect();
        self.err_at(
            pos,
            format!("'{}'", item.trim()),
            format!(
                "a library of at most {MAX_SPEC_TERMS} terms in all (this item takes it past that); narrow the ranges"
            ),
        )
    }

    fn poly(&mut self, budget: usize) -> Result<Vec<Term>> {
        let start = {
            self.skip_ws();
            self.pos
        };
        self.ident();
        self.expect('(', "'(' after poly")?;
        let mut vars = vec![self.var()?];
        while self.eat(',') {
            vars.push(self.var()?);
        }
        self.expect(';', "';' then a degree range, as in poly(x, x'; 0..7)")?;
        let lo = self.uint("the lowest total degree, as in poly(x, x'; 0..7)")?;
        if !(self.eat('.') && self.chars.get(self.pos) == Some(&'.')) {
            return Err(self.err("'..' and the highest total degree, as in poly(x, x'; 0..7)"));
        }
        self.pos += 1;
        let hpos = {
            self.skip_ws();
            self.pos
        };
        let hi = self.uint("the highest total degree")?;
        if hi < lo {
            return Err(self.err_at(
                hpos,
                format!("'{hi}'"),
                format!("a highest degree not below the lowest degree {lo}"),
            ));
        }
        self.expect(')', "')' closing poly(")?;
        if hi > MAX_POWER {
            return Err(self.err_at(
                hpos,
                format!("'{hi}'"),
                format!("a total degree of at most {MAX_POWER}"),
            ));
        }
        // Monomials of degree d in v variables: C(d + v - 1, v - 1), counted before building.
        let v = vars.len() as u128;
        let mut count: u128 = 0;
        for d in lo..=hi {
            let mut c: u128 = 1;
            for i in 1..v {
                c = c * (d as u128 + i) / i;
                if c > budget as u128 {
                    break;
                }
            }
            count += c;
            if count > budget as u128 {
                return Err(self.too_many(start));
            }
        }
        let mut out = Vec::new();
        for d in lo..=hi {
            let mut exps = vec![0u32; vars.len()];
            monomials(&vars, &mut exps, 0, d, &mut out);
        }
        Ok(out)
    }

    /// One list item, expanding to at most `budget` terms.
    fn item(&mut self, budget: usize) -> Result<Vec<Term>> {
        if self.at_call("poly") {
            if !self.allow_ranges {
                return Err(self.err("a single term; poly(...) is only allowed in library specs"));
            }
            self.poly(budget)
        } else {
            self.product(budget)
        }
    }
}

/// Appends every monomial of total degree `remaining` in `vars[i..]`, earlier variables with the
/// highest powers first (`x^2`, `x*x'`, `x'^2`).
fn monomials(vars: &[Var], exps: &mut Vec<u32>, i: usize, remaining: u32, out: &mut Vec<Term>) {
    if i + 1 == vars.len() {
        exps[i] = remaining;
        out.push(Term::new(
            vars.iter()
                .zip(exps.iter())
                .map(|(v, k)| Factor::Pow(v.clone(), *k))
                .collect(),
        ));
        return;
    }
    for k in (0..=remaining).rev() {
        exps[i] = k;
        monomials(vars, exps, i + 1, remaining - k, out);
    }
}

/// Parses a single term.
pub(crate) fn parse_term(text: &str, dofs: &[&str]) -> Result<Term> {
    let mut p = Parser::new(text, dofs, false);
    if p.at_end() {
        return Err(p.err("a term such as x^3 or x'"));
    }
    let mut terms = p.item(1)?;
    if !p.at_end() {
        return Err(p.err("'*' or the end of the term"));
    }
    // Without ranges a product yields exactly one term.
    Ok(terms.pop().unwrap_or_default())
}

/// Parses a comma-separated library spec into terms (duplicates kept; the caller removes them).
/// The expansion is bounded by [`MAX_SPEC_TERMS`] before anything is built.
pub(crate) fn parse_spec(text: &str, dofs: &[&str]) -> Result<Vec<Term>> {
    let mut p = Parser::new(text, dofs, true);
    if p.at_end() {
        return Err(p.err("a library spec such as \"x^1..7, x'\""));
    }
    let mut out = p.item(MAX_SPEC_TERMS)?;
    loop {
        if p.at_end() {
            break;
        }
        if !p.eat(',') {
            return Err(p.err("',' between terms, '*' inside a product, or the end of the spec"));
        }
        let more = p.item(MAX_SPEC_TERMS - out.len())?;
        out.extend(more);
    }
    Ok(out)
}
