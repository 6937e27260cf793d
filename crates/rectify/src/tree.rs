//! A small reader for the structured text calibration files are written in: the YAML subset
//! OpenCV's `FileStorage` and ROS's `camera_calibration` write (block mappings, block and flow
//! sequences, `%YAML:1.0` directives, `!!opencv-matrix` tags), JSON (which is flow YAML), and
//! OpenCV's `FileStorage` XML. Everything becomes a [`Node`] tree; scalars stay text.

/// A parsed value.
#[derive(Clone, Debug, PartialEq)]
pub enum Node {
    Scalar(String),
    Seq(Vec<Node>),
    Map(Vec<(String, Node)>),
}

impl Node {
    /// The value of `key` in a mapping.
    pub fn get(&self, key: &str) -> Option<&Node> {
        match self {
            Node::Map(entries) => entries.iter().find(|(k, _)| k == key).map(|(_, v)| v),
            _ => None,
        }
    }

    /// The first of `keys` present in a mapping, with the key found.
    pub fn get_any<'a>(&'a self, keys: &[&'a str]) -> Option<(&'a str, &'a Node)> {
        keys.iter().find_map(|k| self.get(k).map(|v| (*k, v)))
    }

    /// Every number below this node, in order: scalars may hold several, separated by spaces or
    /// commas (XML `<data>` elements do).
    pub fn numbers(&self) -> Result<Vec<f64>, String> {
        let mut out = Vec::new();
        self.collect_numbers(&mut out)?;
        Ok(out)
    }

    fn collect_numbers(&self, out: &mut Vec<f64>) -> Result<(), String> {
        match self {
            Node::Scalar(text) => {
                for word in text.split(|c: char| c.is_whitespace() || c == ',').filter(|w| !w.is_empty()) {
                    let v = parse_number(word).ok_or_else(|| format!("{word:?} is not a number"))?;
                    out.push(v);
                }
                Ok(())
            }
            Node::Seq(items) => items.iter().try_for_each(|item| item.collect_numbers(out)),
            Node::Map(_) => Err("a mapping where numbers were expected".into()),
        }
    }

    /// The text of a scalar.
    pub fn text(&self) -> Option<&str> {
        match self {
            Node::Scalar(text) => Some(text),
            _ => None,
        }
    }
}

/// A number as calibration files write them: `1.`, `-2.5e-03`, `.5`, and OpenCV's `.Nan`/`.Inf`
/// (refused: a calibration needs finite numbers).
fn parse_number(word: &str) -> Option<f64> {
    let word = word.trim_matches(|c| c == '"' || c == '\'');
    word.parse::<f64>().ok().filter(|v| v.is_finite())
}

/// Parses a file's text, detected from its first significant character: `<` XML, `{` or `[`
/// JSON/flow YAML, anything else block YAML.
pub fn parse(text: &str) -> Result<Node, String> {
    let text = text.strip_prefix('\u{feff}').unwrap_or(text);
    let start = text.trim_start();
    if start.starts_with('<') {
        return parse_xml(start);
    }
    if start.starts_with('{') || start.starts_with('[') {
        let mut parser = Flow { chars: start.chars().collect(), pos: 0 };
        let node = parser.value()?;
        parser.skip_space();
        if parser.pos < parser.chars.len() {
            return Err(format!("unexpected text after the document: {:?}", parser.rest(20)));
        }
        return Ok(node);
    }
    parse_block_yaml(text)
}

// ---------------------------------------------------------------------------------------------
// Flow YAML / JSON

struct Flow {
    chars: Vec<char>,
    pos: usize,
}

impl Flow {
    fn rest(&self, n: usize) -> String {
        self.chars[self.pos..].iter().take(n).collect()
    }

    fn skip_space(&mut self) {
        while self.pos < self.chars.len() {
            let c = self.chars[self.pos];
            if c.is_whitespace() {
                self.pos += 1;
            } else if c == '#' {
                while self.pos < self.chars.len() && self.chars[self.pos] != '\n' {
                    self.pos += 1;
                }
            } else {
                break;
            }
        }
    }

    fn peek(&self) -> Option<char> {
        self.chars.get(self.pos).copied()
    }

    fn value(&mut self) -> Result<Node, String> {
        self.skip_space();
        // Tags (`!!opencv-matrix`) carry nothing we need.
        while self.peek() == Some('!') {
            while self.peek().is_some_and(|c| !c.is_whitespace()) {
                self.pos += 1;
            }
            self.skip_space();
        }
        match self.peek() {
            Some('[') => {
                self.pos += 1;
                let mut items = Vec::new();
                loop {
                    self.skip_space();
                    if self.peek() == Some(']') {
                        self.pos += 1;
                        return Ok(Node::Seq(items));
                    }
                    items.push(self.value()?);
                    self.skip_space();
                    match self.peek() {
                        Some(',') => self.pos += 1,
                        Some(']') => {}
                        _ => return Err(format!("expected ',' or ']' in a list at {:?}", self.rest(20))),
                    }
                }
            }
            Some('{') => {
                self.pos += 1;
                let mut entries = Vec::new();
                loop {
                    self.skip_space();
                    if self.peek() == Some('}') {
                        self.pos += 1;
                        return Ok(Node::Map(entries));
                    }
                    let key = match self.value()? {
                        Node::Scalar(k) => k,
                        _ => return Err("a mapping key must be text".into()),
                    };
                    self.skip_space();
                    if self.peek() != Some(':') {
                        return Err(format!("expected ':' after {key:?}"));
                    }
                    self.pos += 1;
                    let value = self.value()?;
                    entries.push((key, value));
                    self.skip_space();
                    match self.peek() {
                        Some(',') => self.pos += 1,
                        Some('}') => {}
                        _ => return Err(format!("expected ',' or '}}' in a mapping at {:?}", self.rest(20))),
                    }
                }
            }
            Some(q @ ('"' | '\'')) => {
                self.pos += 1;
                let mut s = String::new();
                while let Some(c) = self.peek() {
                    self.pos += 1;
                    if c == q {
                        return Ok(Node::Scalar(s));
                    }
                    if c == '\\' && q == '"' {
                        if let Some(e) = self.peek() {
                            self.pos += 1;
                            s.push(match e {
                                'n' => '\n',
                                't' => '\t',
                                other => other,
                            });
                        }
                    } else {
                        s.push(c);
                    }
                }
                Err("unterminated quoted string".into())
            }
            Some(_) => {
                let start = self.pos;
                while let Some(c) = self.peek() {
                    // A ':' ends a plain key only when followed by a space (YAML), or always in
                    // JSON-like flow (keys are then quoted anyway).
                    if matches!(c, ',' | ']' | '}' | '\n') || (c == ':' && self.next_is_space()) {
                        break;
                    }
                    self.pos += 1;
                }
                let word: String = self.chars[start..self.pos].iter().collect();
                Ok(Node::Scalar(word.trim().to_string()))
            }
            None => Err("unexpected end of the document".into()),
        }
    }

    fn next_is_space(&self) -> bool {
        !matches!(self.chars.get(self.pos + 1), Some(c) if !c.is_whitespace())
    }
}

// ---------------------------------------------------------------------------------------------
// Block YAML

struct Line {
    indent: usize,
    text: String,
    number: usize,
}

/// Strips a comment: `#` at the start or after a space, outside quotes.
fn strip_comment(line: &str) -> &str {
    let mut quote = None;
    let mut prev_space = true;
    for (i, c) in line.char_indices() {
        match quote {
            Some(q) if c == q => quote = None,
            Some(_) => {}
            None if c == '"' || c == '\'' => quote = Some(c),
            None if c == '#' && prev_space => return &line[..i],
            None => {}
        }
        prev_space = c.is_whitespace();
    }
    line
}

fn parse_block_yaml(text: &str) -> Result<Node, String> {
    let mut lines = Vec::new();
    for (i, raw) in text.lines().enumerate() {
        let trimmed_start = raw.trim_start();
        if trimmed_start.starts_with('%')
            || trimmed_start.starts_with("---")
            || trimmed_start.starts_with("...")
        {
            continue;
        }
        let line = strip_comment(raw).trim_end();
        if line.trim().is_empty() {
            continue;
        }
        let indent = line.len() - line.trim_start().len();
        lines.push(Line { indent, text: line.trim_start().to_string(), number: i + 1 });
    }
    if lines.is_empty() {
        return Err("empty document".into());
    }
    let mut pos = 0;
    let node = block(&lines, &mut pos, lines[0].indent)?;
    if pos < lines.len() {
        return Err(format!("line {}: unexpected indentation", lines[pos].number));
    }
    Ok(node)
}

/// Splits `key: rest` at the first `: ` (or a trailing `:`) outside quotes and brackets.
fn split_key(text: &str) -> Option<(String, &str)> {
    let mut depth = 0i32;
    let mut quote = None;
    let bytes: Vec<char> = text.chars().collect();
    let mut byte_pos = 0;
    for (i, &c) in bytes.iter().enumerate() {
        match quote {
            Some(q) if c == q => quote = None,
            Some(_) => {}
            None => match c {
                '"' | '\'' => quote = Some(c),
                '[' | '{' => depth += 1,
                ']' | '}' => depth -= 1,
                ':' if depth == 0 && !matches!(bytes.get(i + 1), Some(n) if !n.is_whitespace()) => {
                    let key = text[..byte_pos].trim().trim_matches(|c| c == '"' || c == '\'').to_string();
                    return Some((key, text[byte_pos + 1..].trim()));
                }
                _ => {}
            },
        }
        byte_pos += c.len_utf8();
    }
    None
}

/// Strips leading tags (`!!opencv-matrix`).
fn strip_tags(mut text: &str) -> &str {
    while text.starts_with('!') {
        text = text.find(char::is_whitespace).map_or("", |i| text[i..].trim_start());
    }
    text
}

/// Whether the flow text has balanced brackets (outside quotes).
fn balance(text: &str) -> i32 {
    let mut depth = 0;
    let mut quote = None;
    for c in text.chars() {
        match quote {
            Some(q) if c == q => quote = None,
            Some(_) => {}
            None => match c {
                '"' | '\'' => quote = Some(c),
                '[' | '{' => depth += 1,
                ']' | '}' => depth -= 1,
                _ => {}
            },
        }
    }
    depth
}

/// An inline value; a flow collection may continue on the following lines.
fn inline_value(first: &str, lines: &[Line], pos: &mut usize) -> Result<Node, String> {
    let mut text = first.to_string();
    while balance(&text) > 0 {
        let Some(next) = lines.get(*pos) else { return Err("unclosed '[' or '{'".into()) };
        text.push(' ');
        text.push_str(&next.text);
        *pos += 1;
    }
    if text.starts_with('[') || text.starts_with('{') || text.starts_with('"') || text.starts_with('\'') {
        let mut parser = Flow { chars: text.chars().collect(), pos: 0 };
        return parser.value();
    }
    Ok(Node::Scalar(text.trim().to_string()))
}

fn block(lines: &[Line], pos: &mut usize, indent: usize) -> Result<Node, String> {
    let first = &lines[*pos];
    if first.text == "-" || first.text.starts_with("- ") {
        let mut items = Vec::new();
        while let Some(line) = lines.get(*pos) {
            if line.indent < indent {
                break;
            }
            if line.indent > indent {
                return Err(format!("line {}: unexpected indentation", line.number));
            }
            if !(line.text == "-" || line.text.starts_with("- ")) {
                break;
            }
            let rest = strip_tags(line.text[1..].trim());
            *pos += 1;
            if rest.is_empty() {
                match lines.get(*pos) {
                    Some(next) if next.indent > indent => items.push(block(lines, pos, next.indent)?),
                    _ => items.push(Node::Scalar(String::new())),
                }
            } else if split_key(rest).is_some() && !rest.starts_with('[') && !rest.starts_with('{') {
                return Err(format!("line {}: mappings inside block lists are not supported", line.number));
            } else {
                items.push(inline_value(rest, lines, pos)?);
            }
        }
        return Ok(Node::Seq(items));
    }
    let mut entries = Vec::new();
    while let Some(line) = lines.get(*pos) {
        if line.indent < indent {
            break;
        }
        if line.indent > indent {
            return Err(format!("line {}: unexpected indentation", line.number));
        }
        let (key, rest) =
            split_key(&line.text).ok_or_else(|| format!("line {}: expected 'key: value'", line.number))?;
        let rest = strip_tags(rest);
        *pos += 1;
        let value = if rest.is_empty() {
            match lines.get(*pos) {
                // A nested block; a list may sit at the key's own indentation.
                Some(next)
                    if next.indent > indent
                        || (next.indent == indent && (next.text == "-" || next.text.starts_with("- "))) =>
                {
                    block(lines, pos, next.indent)?
                }
                _ => Node::Scalar(String::new()),
            }
        } else {
            inline_value(rest, lines, pos)?
        };
        entries.push((key, value));
    }
    Ok(Node::Map(entries))
}

// ---------------------------------------------------------------------------------------------
// XML (OpenCV FileStorage)

fn parse_xml(text: &str) -> Result<Node, String> {
    let mut p = Xml { text, pos: 0 };
    p.skip_misc();
    let (name, node) = p.element()?;
    let _ = name;
    Ok(node)
}

struct Xml<'a> {
    text: &'a str,
    pos: usize,
}

impl<'a> Xml<'a> {
    fn rest(&self) -> &'a str {
        &self.text[self.pos..]
    }

    /// Skips whitespace, `<?...?>` declarations and `<!-- -->` comments.
    fn skip_misc(&mut self) {
        loop {
            let trimmed = self.rest().trim_start();
            self.pos = self.text.len() - trimmed.len();
            if trimmed.starts_with("<?") {
                match trimmed.find("?>") {
                    Some(end) => self.pos += end + 2,
                    None => self.pos = self.text.len(),
                }
            } else if trimmed.starts_with("<!--") {
                match trimmed.find("-->") {
                    Some(end) => self.pos += end + 3,
                    None => self.pos = self.text.len(),
                }
            } else {
                return;
            }
        }
    }

    /// An element at `pos` (which is at `<`): children become a mapping (repeated `_` elements,
    /// OpenCV's sequence items, a list), text a scalar.
    fn element(&mut self) -> Result<(String, Node), String> {
        let rest = self.rest();
        if !rest.starts_with('<') {
            return Err(format!("expected an XML element at {:?}", &rest[..rest.len().min(20)]));
        }
        let end = rest.find('>').ok_or("unclosed XML tag")?;
        let tag = &rest[1..end];
        let self_closing = tag.ends_with('/');
        let tag = tag.trim_end_matches('/');
        let name = tag.split_whitespace().next().unwrap_or("").to_string();
        if name.is_empty() {
            return Err("XML element without a name".into());
        }
        self.pos += end + 1;
        if self_closing {
            return Ok((name, Node::Scalar(String::new())));
        }
        let mut children: Vec<(String, Node)> = Vec::new();
        let mut text = String::new();
        loop {
            self.skip_misc_keep_text(&mut text);
            let rest = self.rest();
            if rest.is_empty() {
                return Err(format!("<{name}> is not closed"));
            }
            if let Some(after) = rest.strip_prefix("</") {
                let end = after.find('>').ok_or("unclosed XML tag")?;
                if after[..end].trim() != name {
                    return Err(format!("<{name}> closed by </{}>", after[..end].trim()));
                }
                self.pos += 2 + end + 1;
                break;
            }
            children.push(self.element()?);
        }
        if children.is_empty() {
            return Ok((name, Node::Scalar(text.trim().to_string())));
        }
        if children.iter().all(|(n, _)| n == "_") {
            return Ok((name, Node::Seq(children.into_iter().map(|(_, v)| v).collect())));
        }
        Ok((name, Node::Map(children)))
    }

    /// Collects text up to the next tag, skipping comments.
    fn skip_misc_keep_text(&mut self, text: &mut String) {
        loop {
            let rest = self.rest();
            let next = rest.find('<').unwrap_or(rest.len());
            text.push_str(&rest[..next]);
            self.pos += next;
            let rest = self.rest();
            if rest.starts_with("<!--") {
                match rest.find("-->") {
                    Some(end) => self.pos += end + 3,
                    None => self.pos = self.text.len(),
                }
            } else {
                return;
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn opencv_yaml() {
        let text = "%YAML:1.0\n---\nK1: !!opencv-matrix\n   rows: 3\n   cols: 3\n   dt: d\n   data: [ 1., 0., 3.2e+02, 0., 1.,\n       2.4e+02, 0., 0., 1. ]\nimageSize: [ 640, 480 ]\nname: \"a b\" # comment\n";
        let n = parse(text).unwrap();
        let k1 = n.get("K1").unwrap();
        assert_eq!(k1.get("rows").unwrap().text(), Some("3"));
        assert_eq!(k1.get("data").unwrap().numbers().unwrap(), vec![1., 0., 320., 0., 1., 240., 0., 0., 1.]);
        assert_eq!(n.get("imageSize").unwrap().numbers().unwrap(), vec![640., 480.]);
        assert_eq!(n.get("name").unwrap().text(), Some("a b"));
    }

    #[test]
    fn block_lists_and_json() {
        let n = parse("T:\n- [1, 2]\n- [3, 4]\nx: 5\n").unwrap();
        assert_eq!(n.get("T").unwrap().numbers().unwrap(), vec![1., 2., 3., 4.]);
        let n = parse("{\"K1\": [[1, 0, 2], [0, 1, 3], [0, 0, 1]], \"T\": [-0.1, 0, 0]}").unwrap();
        assert_eq!(n.get("T").unwrap().numbers().unwrap(), vec![-0.1, 0., 0.]);
    }

    #[test]
    fn opencv_xml() {
        let text = "<?xml version=\"1.0\"?>\n<opencv_storage>\n<K1 type_id=\"opencv-matrix\">\n  <rows>3</rows>\n  <cols>3</cols>\n  <dt>d</dt>\n  <data>\n    1. 0. 320. 0. 1. 240. 0. 0. 1.</data></K1>\n<!-- c -->\n<imageSize>\n  640 480</imageSize>\n</opencv_storage>\n";
        let n = parse(text).unwrap();
        assert_eq!(n.get("K1").unwrap().get("data").unwrap().numbers().unwrap().len(), 9);
        assert_eq!(n.get("imageSize").unwrap().numbers().unwrap(), vec![640., 480.]);
    }
}
