//! Lexing: BT.CPP's lenient XML syntax read into a flat list of elements
//! (element 0 is the root), each located by line and column.

use super::*;

#[derive(Debug)]
pub(super) struct Attr {
    pub(super) name: String,
    pub(super) value: String,
    pub(super) loc: Loc,
}

#[derive(Debug)]
pub(super) struct Elem {
    /// Index of the source file (0: the main tree file).
    pub(super) doc: usize,
    pub(super) name: String,
    pub(super) loc: Loc,
    pub(super) attrs: Vec<Attr>,
    pub(super) children: Vec<usize>,
    /// Location of the first non-whitespace text directly inside.
    pub(super) text: Option<Loc>,
}

impl Elem {
    pub(super) fn attr(&self, name: &str) -> Option<&Attr> {
        self.attrs.iter().find(|a| a.name == name)
    }
}

pub(super) struct Reader<'a> {
    pub(super) src: &'a str,
    pub(super) file: &'a str,
    pub(super) doc: usize,
    pub(super) pos: usize,
    pub(super) line: usize,
    pub(super) col: usize,
}

impl<'a> Reader<'a> {
    pub(super) fn loc(&self) -> Loc {
        (self.line, self.col)
    }

    pub(super) fn err(&self, kind: Kind, at: Loc, msg: impl Into<String>) -> TreeError {
        TreeError::at(kind, self.file, self.src, at, msg)
    }

    pub(super) fn rest(&self) -> &'a str {
        &self.src[self.pos..]
    }

    pub(super) fn peek(&self) -> Option<char> {
        self.rest().chars().next()
    }

    pub(super) fn bump(&mut self) -> Option<char> {
        let c = self.peek()?;
        self.pos += c.len_utf8();
        if c == '\n' {
            self.line += 1;
            self.col = 1;
        } else {
            self.col += 1;
        }
        Some(c)
    }

    pub(super) fn starts_with(&self, s: &str) -> bool {
        self.rest().starts_with(s)
    }

    /// Consumes `s` if the input continues with it.
    pub(super) fn eat(&mut self, s: &str) -> bool {
        if !self.starts_with(s) {
            return false;
        }
        for _ in s.chars() {
            self.bump();
        }
        true
    }

    pub(super) fn skip_ws(&mut self) -> bool {
        let mut any = false;
        while matches!(self.peek(), Some(' ' | '\t' | '\r' | '\n')) {
            self.bump();
            any = true;
        }
        any
    }

    /// Consumes everything up to and including `end`; `what` names the
    /// construct opened at `start` for the error.
    pub(super) fn skip_past(&mut self, end: &str, start: Loc, what: &str) -> Result<(), TreeError> {
        match self.rest().find(end) {
            Some(i) => {
                let stop = self.pos + i + end.len();
                while self.pos < stop {
                    self.bump();
                }
                Ok(())
            }
            None => Err(self
                .err(Kind::Syntax, start, format!("unterminated {what}"))
                .with_help(format!("close it with `{end}`"))),
        }
    }

    pub(super) fn name(&mut self, what: &str) -> Result<String, TreeError> {
        let at = self.loc();
        match self.peek() {
            Some(c) if c.is_alphabetic() || c == '_' || c == ':' => {}
            Some(c) => {
                return Err(self
                    .err(Kind::Syntax, at, format!("expected {what}, found {c:?}"))
                    .with_help("XML names start with a letter or `_`"))
            }
            None => {
                return Err(self.err(
                    Kind::Syntax,
                    at,
                    format!("expected {what}, found the end of the file"),
                ))
            }
        }
        let start = self.pos;
        while let Some(c) = self.peek() {
            if c.is_alphanumeric() || matches!(c, '_' | ':' | '-' | '.') {
                self.bump();
            } else {
                break;
            }
        }
        Ok(self.src[start..self.pos].to_string())
    }

    /// Skips comments and whitespace; refuses DOCTYPE, processing
    /// instructions and CDATA wherever markup may appear.
    pub(super) fn misc(&mut self) -> Result<(), TreeError> {
        loop {
            self.skip_ws();
            let at = self.loc();
            if self.starts_with("<!--") {
                // BT.CPP (tinyxml2) accepts `--` inside comments: the
                // comment ends at the first `-->` after `<!--`
                self.eat("<!--");
                self.skip_past("-->", at, "comment")?;
            } else if self.starts_with("<![CDATA[") {
                return Err(self
                    .err(Kind::Syntax, at, "CDATA sections are not supported")
                    .with_help("a behavior tree needs no text content; remove the CDATA section"));
            } else if self.starts_with("<!") {
                return Err(self
                    .err(
                        Kind::Syntax,
                        at,
                        "DOCTYPE and other declarations are not supported",
                    )
                    .with_help("remove the declaration; BT.CPP files do not need it"));
            } else if self.starts_with("<?") {
                return Err(self
                    .err(
                        Kind::Syntax,
                        at,
                        "processing instructions are not supported",
                    )
                    .with_help("only `<?xml ...?>` at the very start of the file is accepted"));
            } else {
                return Ok(());
            }
        }
    }

    /// Decodes entity and character references in `raw`. Like BT.CPP's
    /// parser (tinyxml2), a `&` that does not start a known reference is
    /// kept as it is (`a && b` in scripts).
    pub(super) fn decode(raw: &str) -> String {
        if !raw.contains('&') {
            return raw.to_string();
        }
        let mut out = String::with_capacity(raw.len());
        let mut rest = raw;
        while let Some(i) = rest.find('&') {
            out.push_str(&rest[..i]);
            let tail = &rest[i + 1..];
            let ch = tail.find(';').filter(|&e| e <= 12).and_then(|end| {
                let ent = &tail[..end];
                let c = match ent {
                    "lt" => Some('<'),
                    "gt" => Some('>'),
                    "amp" => Some('&'),
                    "quot" => Some('"'),
                    "apos" => Some('\''),
                    _ => {
                        let num = if let Some(h) = ent.strip_prefix("#x") {
                            (!h.is_empty() && h.chars().all(|c| c.is_ascii_hexdigit()))
                                .then(|| u32::from_str_radix(h, 16).ok())
                                .flatten()
                        } else if let Some(d) = ent.strip_prefix('#') {
                            (!d.is_empty() && d.chars().all(|c| c.is_ascii_digit()))
                                .then(|| d.parse::<u32>().ok())
                                .flatten()
                        } else {
                            None
                        };
                        num.and_then(char::from_u32).filter(|&c| xml_char(c))
                    }
                };
                c.map(|c| (c, end))
            });
            match ch {
                Some((c, end)) => {
                    out.push(c);
                    rest = &tail[end + 1..];
                }
                None => {
                    out.push('&');
                    rest = tail;
                }
            }
        }
        out.push_str(rest);
        out
    }

    pub(super) fn attr_value(&mut self) -> Result<String, TreeError> {
        let at = self.loc();
        let quote = match self.peek() {
            Some(q @ ('"' | '\'')) => q,
            _ => {
                return Err(self
                    .err(Kind::Syntax, at, "expected a quoted attribute value")
                    .with_help("write attributes as name=\"value\" or name='value'"))
            }
        };
        self.bump();
        let start = self.pos;
        loop {
            match self.peek() {
                None => {
                    return Err(self
                        .err(Kind::Syntax, at, "unterminated attribute value")
                        .with_help(format!("close the value with {quote}")))
                }
                Some('<') => {
                    return Err(self
                        .err(Kind::Syntax, self.loc(), "`<` inside an attribute value")
                        .with_help("write it as &lt;"))
                }
                Some(c) if c == quote => break,
                Some(_) => {
                    self.bump();
                }
            }
        }
        let raw = &self.src[start..self.pos];
        self.bump();
        // attribute-value normalisation: white space characters become spaces
        let v = Self::decode(raw);
        Ok(v.replace(['\t', '\n', '\r'], " "))
    }

    /// Skips comments, white space and stray text (which BT.CPP's parser
    /// accepts outside the root element too, e.g. `// clang-format off`).
    pub(super) fn misc_and_text(&mut self) -> Result<(), TreeError> {
        loop {
            self.misc()?;
            match self.peek() {
                Some('<') | None => return Ok(()),
                Some(_) => {
                    while !matches!(self.peek(), Some('<') | None) {
                        self.bump();
                    }
                }
            }
        }
    }

    pub(super) fn parse(mut self) -> Result<Vec<Elem>, TreeError> {
        if let Some((i, c)) = self
            .src
            .char_indices()
            .find(|&(_, c)| !xml_char(c) && c != '\u{feff}')
        {
            let before = &self.src[..i];
            let line = before.matches('\n').count() + 1;
            let col = before.rsplit('\n').next().map_or(0, |l| l.chars().count()) + 1;
            return Err(self
                .err(
                    Kind::Syntax,
                    (line, col),
                    format!("character U+{:04X} is not allowed in XML", c as u32),
                )
                .with_help("is this really a BehaviorTree.CPP XML file?"));
        }
        self.eat("\u{feff}");
        if self.starts_with("<?xml") {
            let at = self.loc();
            self.skip_past("?>", at, "XML declaration")?;
        }
        self.misc_and_text()?;
        if self.peek().is_none() {
            return Err(self
                .err(Kind::Syntax, (1, 1), "the file has no root element")
                .with_help("is this really a BehaviorTree.CPP XML file? It is `<root BTCPP_format=\"4\"> <BehaviorTree ID=\"Main\"> ... </BehaviorTree> </root>`"));
        }
        let mut elems: Vec<Elem> = Vec::new();
        let mut stack: Vec<usize> = Vec::new();
        loop {
            // here we are at markup or text inside the open element on top of
            // the stack (or at the root element if the stack is empty)
            let at = self.loc();
            if self.peek().is_none() {
                let Some(e) = stack.last().map(|&open| &elems[open]) else {
                    return Err(self.err(Kind::Syntax, at, "unexpected end of the file"));
                };
                return Err(self
                    .err(
                        Kind::Syntax,
                        e.loc,
                        format!("element <{}> is never closed", e.name),
                    )
                    .with_help(format!("add </{}>", e.name)));
            }
            if self.starts_with("</") {
                self.eat("</");
                let name = self.name("an element name")?;
                self.skip_ws();
                if !self.eat(">") {
                    return Err(self.err(
                        Kind::Syntax,
                        self.loc(),
                        "expected `>` to end the closing tag",
                    ));
                }
                let Some(&open) = stack.last() else {
                    return Err(self.err(
                        Kind::Syntax,
                        at,
                        format!("closing tag </{name}> without an opening tag"),
                    ));
                };
                if elems[open].name != name {
                    let e = &elems[open];
                    return Err(self
                        .err(
                            Kind::Syntax,
                            at,
                            format!("</{name}> does not close <{}>", e.name),
                        )
                        .with_help(format!(
                            "<{}> opened at line {}, column {} must be closed first",
                            e.name, e.loc.0, e.loc.1
                        )));
                }
                stack.pop();
                if stack.is_empty() {
                    break;
                }
            } else if self.starts_with("<!") || self.starts_with("<?") {
                self.misc()?;
            } else if self.starts_with("<") {
                self.bump();
                let name = self.name("an element name")?;
                let mut attrs: Vec<Attr> = Vec::new();
                let self_closing = loop {
                    let ws = self.skip_ws();
                    if self.eat("/>") {
                        break true;
                    }
                    if self.eat(">") {
                        break false;
                    }
                    let aloc = self.loc();
                    if self.peek().is_none() {
                        return Err(self
                            .err(Kind::Syntax, at, format!("unterminated tag <{name}"))
                            .with_help("end it with `>` or `/>`"));
                    }
                    if !ws {
                        return Err(self
                            .err(Kind::Syntax, aloc, "expected white space, `>` or `/>`")
                            .with_help("separate attributes with spaces"));
                    }
                    let aname = self.name("an attribute name or `>`")?;
                    self.skip_ws();
                    if !self.eat("=") {
                        return Err(self
                            .err(
                                Kind::Syntax,
                                self.loc(),
                                format!("expected `=` after attribute `{aname}`"),
                            )
                            .with_help("write attributes as name=\"value\""));
                    }
                    self.skip_ws();
                    let value = self.attr_value()?;
                    if let Some(prev) = attrs.iter().find(|a| a.name == aname) {
                        return Err(self
                            .err(Kind::Syntax, aloc, format!("duplicate attribute `{aname}`"))
                            .with_help(format!(
                                "`{aname}` is already given at line {}, column {}",
                                prev.loc.0, prev.loc.1
                            )));
                    }
                    attrs.push(Attr {
                        name: aname,
                        value,
                        loc: aloc,
                    });
                };
                let id = elems.len();
                elems.push(Elem {
                    doc: self.doc,
                    name,
                    loc: at,
                    attrs,
                    children: Vec::new(),
                    text: None,
                });
                if let Some(&parent) = stack.last() {
                    elems[parent].children.push(id);
                }
                if self_closing {
                    if stack.is_empty() {
                        break;
                    }
                } else {
                    if stack.len() >= MAX_XML_DEPTH {
                        return Err(self
                            .err(Kind::Budget, at, "the XML is nested too deeply")
                            .with_help(format!(
                                "btrel accepts trees up to {MAX_DEPTH} levels deep"
                            )));
                    }
                    stack.push(id);
                }
            } else {
                let mut first: Option<Loc> = None;
                while let Some(c) = self.peek() {
                    if c == '<' {
                        break;
                    }
                    if first.is_none() && !c.is_whitespace() {
                        first = Some(self.loc());
                    }
                    self.bump();
                }
                if let (Some(f), Some(&top)) = (first, stack.last()) {
                    elems[top].text.get_or_insert(f);
                }
            }
        }
        // after the root element: only comments, white space and text
        self.misc_and_text()?;
        if self.peek().is_some() {
            return Err(self
                .err(Kind::Syntax, self.loc(), "content after the root element")
                .with_help("an XML file has exactly one root element"));
        }
        Ok(elems)
    }
}

pub(super) fn xml_char(c: char) -> bool {
    matches!(c, '\t' | '\n' | '\r')
        || (' '..='\u{d7ff}').contains(&c)
        || ('\u{e000}'..='\u{fffd}').contains(&c)
        || c >= '\u{10000}'
}

/// One element of an XML document as [`scan_elements`] returns it.
#[derive(Debug, Clone)]
pub struct XmlElement {
    /// The element's name (tag).
    pub name: String,
    /// Its attributes, in document order.
    pub attrs: Vec<(String, String)>,
    /// 1-based line and column of its start tag.
    pub line: usize,
    pub column: usize,
    /// Indices of its child elements.
    pub children: Vec<usize>,
}

impl XmlElement {
    /// The value of attribute `name`.
    pub fn attr(&self, name: &str) -> Option<&str> {
        self.attrs
            .iter()
            .find(|(n, _)| n == name)
            .map(|(_, v)| v.as_str())
    }
}

/// Reads an XML document with btrel's strict XML reader and returns its
/// elements in document order (element 0 is the root). `file` names the
/// source in error messages.
pub fn scan_elements(src: &str, file: &str) -> Result<Vec<XmlElement>, TreeError> {
    if src.len() > MAX_BYTES {
        return Err(too_large(file, src.len()));
    }
    let elems = Reader {
        src,
        file,
        doc: 0,
        pos: 0,
        line: 1,
        col: 1,
    }
    .parse()?;
    Ok(elems
        .into_iter()
        .map(|e| XmlElement {
            name: e.name,
            attrs: e.attrs.into_iter().map(|a| (a.name, a.value)).collect(),
            line: e.loc.0,
            column: e.loc.1,
            children: e.children,
        })
        .collect())
}

#[cfg(test)]
mod tests {
    use super::*;

    fn scan(src: &str) -> Result<Vec<XmlElement>, TreeError> {
        scan_elements(src, "t.xml")
    }

    #[test]
    fn elements_in_document_order_with_locations_and_decoded_values() {
        // `<root a="1">` is 12 characters: <B starts at column 13; the
        // start tag of B is 18 characters and the comment 10, so <C starts
        // at column 13 + 18 + 10 = 41
        let e = scan("<root a=\"1\"><B x='&lt;y&gt;'/><!-- c --><C/></root>").unwrap();
        let names: Vec<&str> = e.iter().map(|e| e.name.as_str()).collect();
        assert_eq!(names, ["root", "B", "C"]);
        assert_eq!((e[0].line, e[0].column), (1, 1));
        assert_eq!((e[1].line, e[1].column), (1, 13));
        assert_eq!((e[2].line, e[2].column), (1, 41));
        assert_eq!(e[0].children, [1, 2]);
        assert_eq!(e[0].attr("a"), Some("1"));
        assert_eq!(e[1].attr("x"), Some("<y>"));
        assert!(e[1].children.is_empty());
    }

    #[test]
    fn lenient_like_tinyxml2() {
        // a `&` that starts no known reference is kept; text around the
        // root and inside elements is ignored; a declaration is accepted
        let e =
            scan("<?xml version=\"1.0\"?>\ntext\n<root>\n  words <A s=\"a && b\"/>\n</root>\nmore")
                .unwrap();
        assert_eq!(e.len(), 2);
        assert_eq!(e[1].attr("s"), Some("a && b"));
        // line 4 is `  words <A ...`: <A at column 9
        assert_eq!((e[1].line, e[1].column), (4, 9));
    }

    #[test]
    fn syntax_errors_are_located() {
        // </root> starts at column 10 and closes the open <A>
        let e = scan("<root><A></root>").unwrap_err();
        assert_eq!(e.kind, Kind::Syntax);
        assert_eq!((e.line, e.column), (1, 10));
        assert_eq!(e.message, "</root> does not close <A>");
        let e = scan("<root><![CDATA[x]]></root>").unwrap_err();
        assert_eq!((e.kind, e.line, e.column), (Kind::Syntax, 1, 7));
        let e = scan("<root a=\"1\" a=\"2\"/>").unwrap_err();
        assert_eq!((e.kind, e.column), (Kind::Syntax, 13));
        assert_eq!(e.message, "duplicate attribute `a`");
        let e = scan("").unwrap_err();
        assert_eq!(e.message, "the file has no root element");
        let e = scan("<a/><b/>").unwrap_err();
        assert_eq!((e.kind, e.column), (Kind::Syntax, 5));
    }

    #[test]
    fn nesting_is_bounded() {
        let ok = format!(
            "{}{}",
            "<a>".repeat(MAX_XML_DEPTH),
            "</a>".repeat(MAX_XML_DEPTH)
        );
        assert_eq!(scan(&ok).unwrap().len(), MAX_XML_DEPTH);
        let deep = "<a>".repeat(MAX_XML_DEPTH + 1);
        let e = scan(&deep).unwrap_err();
        assert_eq!(e.kind, Kind::Budget);
        // the element one too deep starts after MAX_XML_DEPTH `<a>`s
        assert_eq!((e.line, e.column), (1, 3 * MAX_XML_DEPTH + 1));
    }
}
