//! libconfig text, the format of ODAS's configuration files (`odaslive -c array.cfg`).
//!
//! A file is a list of settings `name = value;` (`:` may replace `=`; the `;` or `,` after
//! a setting is optional). A value is a scalar (`true`/`false`, an integer — decimal or
//! `0x` hex, an `L`/`LL` suffix allowed —, a float such as `+0.032` or `1E-20`, or a
//! `"string"`, adjacent strings joined), an array `[a, b]`, a list `(a, b)` or a group
//! `{ settings }`. Comments: `#` and `//` to the end of the line, `/* … */`. `@include`
//! is refused (an array file should stand alone). Errors name the file and the line.

use crate::{Error, Result};
use std::path::Path;

/// Deepest nesting of groups, lists and arrays accepted (a hostile file cannot exhaust
/// the stack).
pub const MAX_DEPTH: usize = 64;

/// A libconfig value. Arrays and lists are both [`Value::List`].
#[derive(Debug, Clone, PartialEq)]
pub enum Value {
    /// `true` / `false`.
    Bool(bool),
    /// An integer.
    Int(i64),
    /// A float.
    Float(f64),
    /// A string.
    Str(String),
    /// An array `[…]` or a list `(…)`.
    List(Vec<Value>),
    /// A group `{…}`: its settings in file order.
    Group(Vec<(String, Value)>),
}

impl Value {
    /// The setting `name` of a group (the first of that name), or None.
    pub fn get(&self, name: &str) -> Option<&Value> {
        match self {
            Value::Group(s) => s.iter().find(|(n, _)| n == name).map(|(_, v)| v),
            _ => None,
        }
    }

    /// A number as f64 (integers converted), or None.
    pub fn as_f64(&self) -> Option<f64> {
        match self {
            Value::Int(i) => Some(*i as f64),
            Value::Float(f) => Some(*f),
            _ => None,
        }
    }

    /// An integer, or None (a float is not one).
    pub fn as_i64(&self) -> Option<i64> {
        match self {
            Value::Int(i) => Some(*i),
            _ => None,
        }
    }

    /// The elements of an array or list, or None.
    pub fn as_list(&self) -> Option<&[Value]> {
        match self {
            Value::List(v) => Some(v),
            _ => None,
        }
    }

    /// What the value is, for messages: "a number", "a list", ….
    pub fn kind(&self) -> &'static str {
        match self {
            Value::Bool(_) => "a boolean",
            Value::Int(_) | Value::Float(_) => "a number",
            Value::Str(_) => "a string",
            Value::List(_) => "a list",
            Value::Group(_) => "a group",
        }
    }
}

/// Parse libconfig `text` into its root group. Errors name `path` and the line.
pub fn parse(text: &str, path: &Path) -> Result<Value> {
    let mut p = Parser {
        s: text.strip_prefix('\u{feff}').unwrap_or(text).as_bytes(),
        i: 0,
        path,
    };
    let settings = p.settings(None, 0)?;
    Ok(Value::Group(settings))
}

struct Parser<'a> {
    s: &'a [u8],
    i: usize,
    path: &'a Path,
}

impl Parser<'_> {
    fn line(&self) -> usize {
        1 + self.s[..self.i.min(self.s.len())]
            .iter()
            .filter(|&&b| b == b'\n')
            .count()
    }

    fn fail<T>(&self, m: impl std::fmt::Display) -> Result<T> {
        Err(Error::format(self.path, format!("line {}: {m}", self.line())))
    }

    fn peek(&self) -> Option<u8> {
        self.s.get(self.i).copied()
    }

    /// What is at the cursor, for messages.
    fn found(&self) -> String {
        match self.peek() {
            None => "the end of the file".into(),
            Some(_) => {
                let rest = String::from_utf8_lossy(&self.s[self.i..(self.i + 12).min(self.s.len())]);
                format!("`{}`", rest.split_whitespace().next().unwrap_or(""))
            }
        }
    }

    /// Skip white space and comments.
    fn blank(&mut self) -> Result<()> {
        loop {
            match self.peek() {
                Some(b) if b.is_ascii_whitespace() => self.i += 1,
                Some(b'#') => self.skip_line(),
                Some(b'/') if self.s.get(self.i + 1) == Some(&b'/') => self.skip_line(),
                Some(b'/') if self.s.get(self.i + 1) == Some(&b'*') => {
                    match self.s[self.i + 2..].windows(2).position(|w| w == b"*/") {
                        Some(k) => self.i += 2 + k + 2,
                        // (The line is counted only here: counting it for every comment
                        // would make a file of many comments quadratic.)
                        None => return self.fail("a /* comment is never closed"),
                    }
                }
                _ => return Ok(()),
            }
        }
    }

    fn skip_line(&mut self) {
        while let Some(b) = self.peek() {
            self.i += 1;
            if b == b'\n' {
                break;
            }
        }
    }

    /// Settings up to `close` (None: the end of the file).
    fn settings(&mut self, close: Option<u8>, depth: usize) -> Result<Vec<(String, Value)>> {
        let mut out = Vec::new();
        loop {
            self.blank()?;
            match (self.peek(), close) {
                (None, None) => return Ok(out),
                (None, Some(c)) => {
                    return self.fail(format!("expected `{}` before the end of the file", c as char))
                }
                (Some(b), Some(c)) if b == c => {
                    self.i += 1;
                    return Ok(out);
                }
                (Some(b'@'), _) => {
                    return self.fail(
                        "@include and other directives are not supported: give one self-contained file",
                    )
                }
                _ => {}
            }
            let name = self.name()?;
            if out.iter().any(|(n, _)| *n == name) {
                return self.fail(format!("`{name}` is set twice in one group"));
            }
            self.blank()?;
            match self.peek() {
                Some(b'=' | b':') => self.i += 1,
                _ => {
                    return self.fail(format!(
                        "expected `=` or `:` after `{name}`, found {}",
                        self.found()
                    ))
                }
            }
            let value = self.value(depth)?;
            self.blank()?;
            if matches!(self.peek(), Some(b';' | b',')) {
                self.i += 1;
            }
            out.push((name, value));
        }
    }

    fn name(&mut self) -> Result<String> {
        let start = self.i;
        match self.peek() {
            Some(b) if b.is_ascii_alphabetic() || b == b'*' => self.i += 1,
            _ => return self.fail(format!("expected a setting name, found {}", self.found())),
        }
        while matches!(self.peek(), Some(b) if b.is_ascii_alphanumeric() || b"-_*".contains(&b)) {
            self.i += 1;
        }
        Ok(String::from_utf8_lossy(&self.s[start..self.i]).into_owned())
    }

    fn value(&mut self, depth: usize) -> Result<Value> {
        if depth >= MAX_DEPTH {
            return self.fail(format!("nested deeper than {MAX_DEPTH} levels"));
        }
        self.blank()?;
        match self.peek() {
            Some(b'{') => {
                self.i += 1;
                Ok(Value::Group(self.settings(Some(b'}'), depth + 1)?))
            }
            Some(open @ (b'(' | b'[')) => {
                self.i += 1;
                let close = if open == b'(' { b')' } else { b']' };
                let mut items = Vec::new();
                loop {
                    self.blank()?;
                    if self.peek() == Some(close) {
                        self.i += 1;
                        return Ok(Value::List(items));
                    }
                    items.push(self.value(depth + 1)?);
                    self.blank()?;
                    match self.peek() {
                        Some(b',') => self.i += 1,
                        Some(c) if c == close => {}
                        _ => {
                            return self.fail(format!(
                                "expected `,` or `{}` in a list, found {}",
                                close as char,
                                self.found()
                            ))
                        }
                    }
                }
            }
            Some(b'"') => {
                let mut s = String::new();
                while self.peek() == Some(b'"') {
                    s.push_str(&self.string()?);
                    self.blank()?;
                }
                Ok(Value::Str(s))
            }
            Some(_) => self.scalar(),
            None => self.fail("expected a value, found the end of the file"),
        }
    }

    fn string(&mut self) -> Result<String> {
        self.i += 1;
        let mut out = Vec::new();
        loop {
            match self.peek() {
                None => return self.fail("a string is never closed"),
                Some(b'"') => {
                    self.i += 1;
                    return String::from_utf8(out).or_else(|_| self.fail("a string is not UTF-8"));
                }
                Some(b'\\') => {
                    let c = self.s.get(self.i + 1).copied();
                    self.i += 2;
                    match c {
                        Some(b'n') => out.push(b'\n'),
                        Some(b't') => out.push(b'\t'),
                        Some(b'r') => out.push(b'\r'),
                        Some(b'f') => out.push(0x0c),
                        Some(b'\\') => out.push(b'\\'),
                        Some(b'"') => out.push(b'"'),
                        Some(b'x') => {
                            let hex = self
                                .s
                                .get(self.i..self.i + 2)
                                .filter(|h| h.iter().all(|b| b.is_ascii_hexdigit()))
                                .and_then(|h| std::str::from_utf8(h).ok());
                            match hex.and_then(|h| u8::from_str_radix(h, 16).ok()) {
                                Some(b) => {
                                    out.push(b);
                                    self.i += 2;
                                }
                                None => {
                                    return self.fail("\\x in a string must be followed by two hex digits")
                                }
                            }
                        }
                        _ => return self.fail("unknown escape in a string"),
                    }
                }
                Some(b) => {
                    out.push(b);
                    self.i += 1;
                }
            }
        }
    }

    fn scalar(&mut self) -> Result<Value> {
        let start = self.i;
        while matches!(self.peek(), Some(b) if b.is_ascii_alphanumeric() || b"+-._".contains(&b)) {
            self.i += 1;
        }
        let word = std::str::from_utf8(&self.s[start..self.i]).unwrap_or("");
        if word.is_empty() {
            return self.fail(format!("expected a value, found {}", self.found()));
        }
        if word.eq_ignore_ascii_case("true") {
            return Ok(Value::Bool(true));
        }
        if word.eq_ignore_ascii_case("false") {
            return Ok(Value::Bool(false));
        }
        let int = word.trim_end_matches(['L', 'l']);
        let (sign, digits) = match int.as_bytes().first() {
            Some(b'-') => (-1i64, &int[1..]),
            Some(b'+') => (1, &int[1..]),
            _ => (1, int),
        };
        let parsed = if let Some(h) = digits.strip_prefix("0x").or_else(|| digits.strip_prefix("0X")) {
            (!h.is_empty() && h.bytes().all(|b| b.is_ascii_hexdigit()))
                .then(|| i64::from_str_radix(h, 16).ok())
                .flatten()
        } else if !digits.is_empty() && digits.bytes().all(|b| b.is_ascii_digit()) {
            digits.parse::<i64>().ok()
        } else {
            None
        };
        if let Some(v) = parsed {
            return Ok(Value::Int(sign * v));
        }
        match word.parse::<f64>() {
            Ok(f) if word.bytes().any(|b| b.is_ascii_digit()) => Ok(Value::Float(f)),
            _ => self.fail(format!("`{word}` is not a number, a boolean or a \"string\"")),
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn p(t: &str) -> Result<Value> {
        parse(t, Path::new("a.cfg"))
    }

    #[test]
    fn every_value_kind_and_comment_style() {
        let v = p(r#"
            version = "2.1";  # a comment
            // another
            /* and a
               block */ raw: { fS = 16000; nBits = 0x10L; eps = 1E-20; on = TRUE; }
            mapping: { map: (2, 3, 4, 5); }
            general = { mics = ( { mu = ( -0.032, +0.000, +0.5 ); }, { mu = [1, 2, 3] } ); name = "a" "b\n\x41"; }
        "#)
        .unwrap();
        assert_eq!(v.get("version"), Some(&Value::Str("2.1".into())));
        let raw = v.get("raw").unwrap();
        assert_eq!(raw.get("fS"), Some(&Value::Int(16000)));
        assert_eq!(raw.get("nBits"), Some(&Value::Int(16)));
        assert_eq!(raw.get("eps"), Some(&Value::Float(1e-20)));
        assert_eq!(raw.get("on"), Some(&Value::Bool(true)));
        let map = v.get("mapping").unwrap().get("map").unwrap().as_list().unwrap();
        assert_eq!(
            map.iter().map(|m| m.as_i64().unwrap()).collect::<Vec<_>>(),
            [2, 3, 4, 5]
        );
        let general = v.get("general").unwrap();
        let mics = general.get("mics").unwrap().as_list().unwrap();
        let mu: Vec<f64> = mics[0]
            .get("mu")
            .unwrap()
            .as_list()
            .unwrap()
            .iter()
            .map(|x| x.as_f64().unwrap())
            .collect();
        assert_eq!(mu, [-0.032, 0.0, 0.5]);
        assert_eq!(mics[1].get("mu").unwrap().as_list().unwrap()[2], Value::Int(3));
        assert_eq!(general.get("name"), Some(&Value::Str("ab\nA".into())));
    }

    #[test]
    fn errors_name_the_file_and_line() {
        let e = |t: &str| p(t).unwrap_err().to_string();
        assert_eq!(e("a = 1;\nb = ;"), "a.cfg: line 2: expected a value, found `;`");
        assert_eq!(
            e("a = (1, 2"),
            "a.cfg: line 1: expected `,` or `)` in a list, found the end of the file"
        );
        assert_eq!(
            e("g = {\n a = 1;\n"),
            "a.cfg: line 3: expected `}` before the end of the file"
        );
        assert_eq!(
            e("a 1"),
            "a.cfg: line 1: expected `=` or `:` after `a`, found `1`"
        );
        assert_eq!(
            e("a = 1.2.3"),
            "a.cfg: line 1: `1.2.3` is not a number, a boolean or a \"string\""
        );
        assert_eq!(e("/* open"), "a.cfg: line 1: a /* comment is never closed");
        assert!(e("@include \"x.cfg\"").contains("@include"));
        assert!(e("s = \"abc").contains("never closed"));
        let deep = format!("a = {}{}", "(".repeat(100), ")".repeat(100));
        assert!(e(&deep).contains("nested deeper than 64"));
        assert_eq!(p("").unwrap(), Value::Group(Vec::new()));
        assert_eq!(
            e("a = 0x-5;"),
            "a.cfg: line 1: `0x-5` is not a number, a boolean or a \"string\""
        );
        assert!(e("s = \"\\x+1\";").contains("two hex digits"));
        assert_eq!(
            e("g = { a = 1;\n a = 2; };"),
            "a.cfg: line 2: `a` is set twice in one group"
        );
        // A byte-order mark is not part of the text.
        assert_eq!(p("\u{feff}a = 1;").unwrap().get("a"), Some(&Value::Int(1)));
        // Many comments take linear time (the line was counted for each of them).
        let many = "/**/".repeat(1 << 20) + "a = 1;";
        assert_eq!(p(&many).unwrap().get("a"), Some(&Value::Int(1)));
    }
}
