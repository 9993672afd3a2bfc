//! A tiny, tolerant XML reader and writer for what HARK writes (`hark_xml` documents:
//! `microphones.xml`, `source.xml`, source-location logs).
//!
//! Not a general XML implementation: no DTDs, no namespaces. It reads elements,
//! attributes (single or double quoted), text, self-closing tags, comments, `<?...?>`
//! declarations, `<!DOCTYPE ...>` and CDATA, and decodes the five predefined entities and
//! numeric character references. It is tolerant where HARK files are sloppy: unknown
//! entities are kept verbatim, and elements still open at end of input are closed
//! implicitly. A close tag that does not match the open element is an error.
//!
//! Typical use:
//! ```
//! use soundloc::formats::xml;
//! let doc = xml::parse(r#"<hark_xml version="1.3"><config><nfft>512</nfft></config>
//!   <positions type="microphone"><position x="0.1" y="0" z="0" id="0"/></positions></hark_xml>"#)
//!   .unwrap();
//! assert_eq!(doc.find("nfft").unwrap().text_trimmed(), "512");
//! let p = doc.find_all("position");
//! assert_eq!(p[0].attr("x"), Some("0.1"));
//! ```
//!
//! Writing: [`escape_attr`] / [`escape_text`] for hand-formatted output, or build an
//! [`Element`] tree and call [`Element::to_xml_string`] (4-space indentation, HARK's style).

use std::fmt;
use std::path::Path;

/// One XML element: name, attributes in document order, child elements and text.
#[derive(Debug, Clone, PartialEq, Default)]
pub struct Element {
    /// Tag name (`position`). The document root returned by [`parse`] is named `#document`.
    pub name: String,
    /// Attributes `(name, value)` in document order, values unescaped.
    pub attrs: Vec<(String, String)>,
    /// Child elements in document order.
    pub children: Vec<Element>,
    /// Concatenated character data directly inside this element (unescaped, untrimmed).
    pub text: String,
}

/// A parse failure: what went wrong and on which 1-based line.
#[derive(Debug, Clone, PartialEq)]
pub struct XmlError {
    /// 1-based line of the problem.
    pub line: usize,
    /// What is wrong.
    pub message: String,
}

impl fmt::Display for XmlError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(f, "XML line {}: {}", self.line, self.message)
    }
}

impl std::error::Error for XmlError {}

impl Element {
    /// A new element with no attributes or children.
    pub fn new(name: impl Into<String>) -> Self {
        Element {
            name: name.into(),
            ..Default::default()
        }
    }
    /// Builder: add an attribute.
    pub fn with_attr(mut self, name: impl Into<String>, value: impl Into<String>) -> Self {
        self.attrs.push((name.into(), value.into()));
        self
    }
    /// Builder: add a child element.
    pub fn with_child(mut self, child: Element) -> Self {
        self.children.push(child);
        self
    }
    /// Builder: set the text content.
    pub fn with_text(mut self, text: impl Into<String>) -> Self {
        self.text = text.into();
        self
    }
    /// The value of attribute `name` (exact, case-sensitive match).
    pub fn attr(&self, name: &str) -> Option<&str> {
        self.attrs
            .iter()
            .find(|(n, _)| n == name)
            .map(|(_, v)| v.as_str())
    }
    /// The text content with surrounding whitespace removed.
    pub fn text_trimmed(&self) -> &str {
        self.text.trim()
    }
    /// The first direct child named `name`.
    pub fn child(&self, name: &str) -> Option<&Element> {
        self.children.iter().find(|c| c.name == name)
    }
    /// All direct children named `name`.
    pub fn children_named<'a>(&'a self, name: &'a str) -> impl Iterator<Item = &'a Element> + 'a {
        self.children.iter().filter(move |c| c.name == name)
    }
    /// The first element named `name` in depth-first document order, this element included.
    pub fn find(&self, name: &str) -> Option<&Element> {
        if self.name == name {
            return Some(self);
        }
        self.children.iter().find_map(|c| c.find(name))
    }
    /// All elements named `name` in depth-first document order, this element included.
    pub fn find_all(&self, name: &str) -> Vec<&Element> {
        let mut out = Vec::new();
        self.collect(name, &mut out);
        out
    }
    fn collect<'a>(&'a self, name: &str, out: &mut Vec<&'a Element>) {
        if self.name == name {
            out.push(self);
        }
        for c in &self.children {
            c.collect(name, out);
        }
    }
    /// Serialise this element (and its subtree) with 4-space indentation starting at
    /// `indent` levels, one element per line, ending with a newline. An element without
    /// children or text but with attributes is written self-closing (`<position .../>`);
    /// text-only elements on
    /// one line (`<nfft>512</nfft>`); an empty element without attributes as
    /// `<TSPpath></TSPpath>` (as HARK writes it). A `#document` element writes only its
    /// children.
    pub fn to_xml_string(&self, indent: usize) -> String {
        let mut s = String::new();
        self.write_into(&mut s, indent);
        s
    }
    fn write_into(&self, s: &mut String, indent: usize) {
        if self.name == "#document" {
            for c in &self.children {
                c.write_into(s, indent);
            }
            return;
        }
        let pad = "    ".repeat(indent);
        s.push_str(&pad);
        s.push('<');
        s.push_str(&self.name);
        for (n, v) in &self.attrs {
            s.push(' ');
            s.push_str(n);
            s.push_str("=\"");
            s.push_str(&escape_attr(v));
            s.push('"');
        }
        if self.children.is_empty() {
            if self.text.is_empty() && !self.attrs.is_empty() {
                s.push_str("/>\n");
            } else {
                s.push('>');
                s.push_str(&escape_text(&self.text));
                s.push_str("</");
                s.push_str(&self.name);
                s.push_str(">\n");
            }
            return;
        }
        s.push_str(">\n");
        if !self.text.trim().is_empty() {
            s.push_str(&pad);
            s.push_str("    ");
            s.push_str(&escape_text(self.text.trim()));
            s.push('\n');
        }
        for c in &self.children {
            c.write_into(s, indent + 1);
        }
        s.push_str(&pad);
        s.push_str("</");
        s.push_str(&self.name);
        s.push_str(">\n");
    }
}

/// Escape text for use inside a double-quoted attribute value.
pub fn escape_attr(s: &str) -> String {
    let mut o = String::with_capacity(s.len());
    for ch in s.chars() {
        match ch {
            '&' => o.push_str("&amp;"),
            '<' => o.push_str("&lt;"),
            '>' => o.push_str("&gt;"),
            '"' => o.push_str("&quot;"),
            '\'' => o.push_str("&apos;"),
            '\n' => o.push_str("&#10;"),
            '\t' => o.push_str("&#9;"),
            '\r' => o.push_str("&#13;"),
            c => o.push(c),
        }
    }
    o
}

/// Escape character data (element text).
pub fn escape_text(s: &str) -> String {
    let mut o = String::with_capacity(s.len());
    for ch in s.chars() {
        match ch {
            '&' => o.push_str("&amp;"),
            '<' => o.push_str("&lt;"),
            '>' => o.push_str("&gt;"),
            c => o.push(c),
        }
    }
    o
}

/// Decode entities (`&amp;` `&lt;` `&gt;` `&quot;` `&apos;` `&#N;` `&#xH;`); unknown or
/// malformed references are kept verbatim.
pub fn unescape(s: &str) -> String {
    if !s.contains('&') {
        return s.to_string();
    }
    let mut o = String::with_capacity(s.len());
    let mut rest = s;
    while let Some(pos) = rest.find('&') {
        o.push_str(&rest[..pos]);
        rest = &rest[pos..];
        let end = rest
            .char_indices()
            .take(12)
            .find(|&(_, c)| c == ';')
            .map(|(i, _)| i);
        let decoded = end.and_then(|e| {
            let ent = &rest[1..e];
            let c = match ent {
                "amp" => Some('&'),
                "lt" => Some('<'),
                "gt" => Some('>'),
                "quot" => Some('"'),
                "apos" => Some('\''),
                _ => {
                    if let Some(h) = ent.strip_prefix("#x").or_else(|| ent.strip_prefix("#X")) {
                        u32::from_str_radix(h, 16).ok().and_then(char::from_u32)
                    } else if let Some(d) = ent.strip_prefix('#') {
                        d.parse::<u32>().ok().and_then(char::from_u32)
                    } else {
                        None
                    }
                }
            };
            c.map(|c| (c, e))
        });
        match decoded {
            Some((c, e)) => {
                o.push(c);
                rest = &rest[e + 1..];
            }
            None => {
                o.push('&');
                rest = &rest[1..];
            }
        }
    }
    o.push_str(rest);
    o
}

/// Deepest element nesting accepted: the tree (and dropping it) is recursive, so a
/// hostile file nested a million levels deep must not reach it.
pub const MAX_DEPTH: usize = 256;

/// Parse a document. Returns a synthetic root element named `#document` whose children
/// are the top-level elements (normally one, `hark_xml`). A leading UTF-8 BOM is skipped.
pub fn parse(text: &str) -> Result<Element, XmlError> {
    Parser {
        s: text.strip_prefix('\u{feff}').unwrap_or(text),
        pos: 0,
    }
    .document()
}

/// [`parse`], with a failure reported as a [`crate::Error::format`] naming `path`.
pub fn parse_file_text(text: &str, path_for_errors: &Path) -> crate::Result<Element> {
    parse(text).map_err(|e| crate::Error::format(path_for_errors, e.to_string()))
}

struct Parser<'a> {
    s: &'a str,
    pos: usize,
}

impl<'a> Parser<'a> {
    fn line(&self) -> usize {
        1 + self.s[..self.pos.min(self.s.len())]
            .bytes()
            .filter(|&b| b == b'\n')
            .count()
    }
    fn err<T>(&self, message: impl Into<String>) -> Result<T, XmlError> {
        Err(XmlError {
            line: self.line(),
            message: message.into(),
        })
    }
    fn rest(&self) -> &'a str {
        &self.s[self.pos..]
    }
    fn skip_ws(&mut self) {
        let r = self.rest();
        self.pos += r.len() - r.trim_start().len();
    }
    /// Advance past the next occurrence of `pat`; error naming `what` if absent.
    fn skip_past(&mut self, pat: &str, what: &str) -> Result<&'a str, XmlError> {
        match self.rest().find(pat) {
            Some(i) => {
                let inner = &self.rest()[..i];
                self.pos += i + pat.len();
                Ok(inner)
            }
            None => self.err(format!("unterminated {what}")),
        }
    }
    fn name(&mut self) -> Result<&'a str, XmlError> {
        let r = self.rest();
        let end = r
            .find(|c: char| c.is_whitespace() || matches!(c, '/' | '>' | '=' | '<' | '"' | '\''))
            .unwrap_or(r.len());
        if end == 0 {
            return self.err("expected a name");
        }
        self.pos += end;
        Ok(&r[..end])
    }

    fn document(mut self) -> Result<Element, XmlError> {
        let mut stack: Vec<Element> = vec![Element::new("#document")];
        while self.pos < self.s.len() {
            let r = self.rest();
            let lt = match r.find('<') {
                Some(i) => i,
                None => {
                    push_text(&mut stack, r);
                    self.pos = self.s.len();
                    break;
                }
            };
            push_text(&mut stack, &r[..lt]);
            self.pos += lt;
            let r = self.rest();
            if r.starts_with("<!--") {
                self.pos += 4;
                self.skip_past("-->", "comment")?;
            } else if r.starts_with("<![CDATA[") {
                self.pos += 9;
                let inner = self.skip_past("]]>", "CDATA section")?;
                if let Some(top) = stack.last_mut() {
                    top.text.push_str(inner);
                }
            } else if r.starts_with("<?") {
                self.pos += 2;
                self.skip_past("?>", "processing instruction")?;
            } else if r.starts_with("<!") {
                self.pos += 2;
                self.skip_past(">", "declaration")?;
            } else if r.starts_with("</") {
                self.pos += 2;
                let name = self.name()?;
                self.skip_ws();
                if !self.rest().starts_with('>') {
                    return self.err(format!("expected '>' after </{name}"));
                }
                self.pos += 1;
                if stack.len() < 2 {
                    return self.err(format!("close tag </{name}> without an open element"));
                }
                let open = stack.last().map(|e| e.name.clone()).unwrap_or_default();
                if open != name {
                    return self.err(format!("close tag </{name}> does not match <{open}>"));
                }
                close_top(&mut stack);
            } else {
                self.pos += 1;
                let name = self.name()?.to_string();
                let mut el = Element::new(name);
                loop {
                    self.skip_ws();
                    let r = self.rest();
                    if r.is_empty() {
                        return self.err(format!("unterminated tag <{}>", el.name));
                    }
                    if r.starts_with("/>") {
                        self.pos += 2;
                        if let Some(top) = stack.last_mut() {
                            top.children.push(el);
                        }
                        break;
                    }
                    if r.starts_with('>') {
                        self.pos += 1;
                        if stack.len() > MAX_DEPTH {
                            return self.err(format!(
                                "elements nested deeper than {MAX_DEPTH} levels (HARK files use fewer than 10)"
                            ));
                        }
                        stack.push(el);
                        break;
                    }
                    let aname = self.name()?.to_string();
                    self.skip_ws();
                    if !self.rest().starts_with('=') {
                        // Attribute without a value (tolerated): empty string.
                        el.attrs.push((aname, String::new()));
                        continue;
                    }
                    self.pos += 1;
                    self.skip_ws();
                    let q = match self.rest().chars().next() {
                        Some(c @ ('"' | '\'')) => c,
                        _ => {
                            // Unquoted value (tolerated): up to whitespace, '/' or '>'.
                            let r = self.rest();
                            let end = r
                                .find(|c: char| c.is_whitespace() || c == '>' || c == '/')
                                .unwrap_or(r.len());
                            el.attrs.push((aname, unescape(&r[..end])));
                            self.pos += end;
                            continue;
                        }
                    };
                    self.pos += 1;
                    let v = self.skip_past(if q == '"' { "\"" } else { "'" }, "attribute value")?;
                    el.attrs.push((aname, unescape(v)));
                }
            }
        }
        // Tolerant: close anything left open at end of input.
        while stack.len() > 1 {
            close_top(&mut stack);
        }
        match stack.pop() {
            Some(root) if root.children.is_empty() => self.err("no element found"),
            Some(root) => Ok(root),
            None => self.err("no element found"),
        }
    }
}

fn push_text(stack: &mut [Element], raw: &str) {
    if raw.is_empty() {
        return;
    }
    if let Some(top) = stack.last_mut() {
        if top.name != "#document" {
            top.text.push_str(&unescape(raw));
        }
    }
}

fn close_top(stack: &mut Vec<Element>) {
    if let Some(el) = stack.pop() {
        if let Some(parent) = stack.last_mut() {
            parent.children.push(el);
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn nesting_is_limited() {
        let deep = "<a>".repeat(1_000_000);
        let e = parse(&deep).unwrap_err();
        assert!(e.to_string().contains("nested deeper than 256"), "{e}");
        let ok = format!("{}{}", "<a>".repeat(200), "</a>".repeat(200));
        assert!(parse(&ok).is_ok());
    }

    #[test]
    fn parses_hark_source_xml_shape() {
        let t = r#"<?xml version="1.0"?>
<hark_xml version="1.3">
    <config>
        <comment>Generated &amp; checked</comment>
        <TSPpath></TSPpath>
        <PeakSearch from="0" to="0"/>
        <nfft>512</nfft>
    </config>
    <!-- a comment <position x="9"/> -->
    <positions type="soundsource" coordinate='cartesian'>
        <position x="0.9578" y="0.0000" z="0.2874" id="0" path="/a&quot;b.wav"/>
        <position x="-1.0" y="2" z="3" id="1"/>
    </positions>
    <neighbors algorithm="NearestNeighbor">
        <neighbor id="0" ids="0;1;"/>
    </neighbors>
</hark_xml>
"#;
        let doc = parse(t).unwrap();
        assert_eq!(doc.children.len(), 1);
        let root = &doc.children[0];
        assert_eq!(root.name, "hark_xml");
        assert_eq!(root.attr("version"), Some("1.3"));
        let cfg = root.child("config").unwrap();
        assert_eq!(cfg.child("nfft").unwrap().text_trimmed(), "512");
        assert_eq!(cfg.child("comment").unwrap().text, "Generated & checked");
        assert_eq!(cfg.child("TSPpath").unwrap().text, "");
        assert_eq!(cfg.child("PeakSearch").unwrap().attr("to"), Some("0"));
        let ps = doc.find_all("position");
        assert_eq!(ps.len(), 2, "commented-out position must not count");
        assert_eq!(ps[0].attr("path"), Some("/a\"b.wav"));
        assert_eq!(ps[1].attr("x"), Some("-1.0"));
        assert_eq!(
            doc.find("positions").unwrap().attr("coordinate"),
            Some("cartesian")
        );
        assert_eq!(doc.find("neighbor").unwrap().attr("ids"), Some("0;1;"));
    }

    #[test]
    fn errors_and_tolerance() {
        let e = parse("<a><b></a>").unwrap_err();
        assert!(e.message.contains("does not match"), "{e}");
        let e = parse("<a>\n<b x=\"1></b></a>").unwrap_err();
        assert!(e.message.contains("unterminated"), "{e}");
        assert!(parse("   ").is_err());
        // Unclosed at EOF: closed implicitly.
        let d = parse("<a><b x=1>t").unwrap();
        assert_eq!(d.find("b").unwrap().attr("x"), Some("1"));
        assert_eq!(d.find("b").unwrap().text, "t");
        assert_eq!(unescape("&#65;&#x42;&bogus;&"), "AB&bogus;&");
    }

    #[test]
    fn write_then_read_back() {
        let el = Element::new("hark_xml")
            .with_attr("version", "1.3")
            .with_child(Element::new("nfft").with_text("512"))
            .with_child(
                Element::new("positions").with_child(Element::new("position").with_attr("path", "<&\"'>")),
            );
        let s = el.to_xml_string(0);
        assert!(s.contains("    <nfft>512</nfft>\n"), "{s}");
        assert!(
            s.contains("<position path=\"&lt;&amp;&quot;&apos;&gt;\"/>"),
            "{s}"
        );
        let back = parse(&s).unwrap();
        assert_eq!(
            back.children[0].find("position").unwrap().attr("path"),
            Some("<&\"'>")
        );
        assert_eq!(back.children[0].child("nfft").unwrap().text, "512");
    }
}
