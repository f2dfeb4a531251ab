//! Tokens of the pbrt-v4 scene format (pbrt-v4 file format documentation,
//! "General syntax"; `Tokenizer::Next` in pbrt-v4's parser.cpp): quoted
//! strings, `[` and `]`, `#` comments to the end of the line, and bare words
//! (directive names, numbers, `true`/`false`) that end at white space, a
//! quote or a bracket.
//!
//! `Include` is token-level, as in pbrt-v4's parser: the lexer reads a
//! stack of files, and the tokens of an included file are followed by those
//! after the `Include` in the file that names it, so a directive may begin
//! in one file and end in another (pbrt-v4-scenes' smoke-plume lists a
//! medium's grid in an included file and its other parameters after the
//! `Include`). Every file read gets its own range of offsets, so a token's
//! offset says which file, line and column it came from.

use crate::error::{Error, Result, SourceLoc};
use arrayvec::ArrayString;
use std::borrow::Cow;
use std::path::{Path, PathBuf};
use std::sync::Arc;

/// A bare word, kept inline when short (numbers nearly always are), so that
/// a mesh of a million numbers is read without a million allocations.
#[derive(Clone, Debug, PartialEq)]
pub(crate) enum Word {
    /// At most 32 bytes.
    Short(ArrayString<32>),
    /// Longer.
    Long(Box<str>),
}

impl Word {
    fn new(s: &str) -> Word {
        ArrayString::from(s).map_or_else(|_| Word::Long(s.into()), Word::Short)
    }
}

impl std::ops::Deref for Word {
    type Target = str;
    fn deref(&self) -> &str {
        match self {
            Word::Short(s) => s,
            Word::Long(s) => s,
        }
    }
}

impl std::fmt::Display for Word {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str(self)
    }
}

/// What a token is.
#[derive(Clone, Debug, PartialEq)]
pub(crate) enum Tok {
    /// A bare word: a directive name, a number, `true` or `false`.
    Word(Word),
    /// A quoted string, without its quotes and with escapes decoded.
    Str(String),
    /// `[`
    Open,
    /// `]`
    Close,
}

impl Tok {
    /// The text of a bare word.
    pub fn word(&self) -> Option<&str> {
        match self {
            Tok::Word(w) => Some(w),
            _ => None,
        }
    }
}

/// A token and the offset where it starts (in the lexer's numbering of
/// the bytes of all the files it read: see [`Lexer::loc`]).
#[derive(Clone, Debug, PartialEq)]
pub(crate) struct Token {
    /// The token.
    pub tok: Tok,
    /// Offset of its first character.
    pub offset: usize,
}

impl Token {
    /// How the token reads in messages.
    pub fn describe(&self) -> String {
        match &self.tok {
            Tok::Word(w) => format!("`{w}`"),
            Tok::Str(s) => format!("the string \"{s}\""),
            Tok::Open => "`[`".into(),
            Tok::Close => "`]`".into(),
        }
    }
}

/// One file that the lexer reads or has read.
struct Source<'t> {
    file: Arc<Path>,
    /// Its folder, relative to the main file's folder (for the names it
    /// gives).
    dir: Arc<Path>,
    /// Its canonical path, for included files (to find include loops).
    canonical: Option<PathBuf>,
    /// The offset of its first byte.
    base: usize,
    len: usize,
    /// Emptied by [`Lexer::release`] once the file is done.
    text: Cow<'t, str>,
    /// Byte offset (within the file) of the start of each line, for
    /// offset → line lookups by binary search (files can have millions of
    /// lines).
    line_starts: Vec<usize>,
    /// Where scanning is, within the file.
    pos: usize,
    released: bool,
}

impl<'t> Source<'t> {
    fn new(file: Arc<Path>, text: Cow<'t, str>, dir: Arc<Path>, canonical: Option<PathBuf>, base: usize) -> Self {
        let mut line_starts = vec![0];
        line_starts.extend(text.match_indices('\n').map(|(i, _)| i + 1));
        Source {
            file,
            dir,
            canonical,
            base,
            len: text.len(),
            text,
            line_starts,
            pos: 0,
            released: false,
        }
    }

    /// The position of byte `local` of the file.
    fn loc(&self, local: usize) -> SourceLoc {
        if self.released {
            // Positions are computed while the directive that holds them is
            // read, before its files are released; this is only a fallback.
            return SourceLoc {
                file: self.file.clone(),
                line: 0,
                column: 0,
            };
        }
        let offset = local.min(self.text.len());
        let line = self.line_starts.partition_point(|&s| s <= offset) - 1;
        let start = self.line_starts[line];
        let mut end = offset;
        while !self.text.is_char_boundary(end) {
            end -= 1;
        }
        SourceLoc {
            file: self.file.clone(),
            line: line as u32 + 1,
            column: self.text[start..end].chars().count() as u32 + 1,
        }
    }
}

/// Splits the text of a file, and of the files it includes, into tokens,
/// and turns offsets into positions.
pub(crate) struct Lexer<'t> {
    /// Every file read, in the order they were opened (so with increasing
    /// `base`); the first is the one the lexer was made for.
    sources: Vec<Source<'t>>,
    /// Indices into `sources` of the files being read, outermost first.
    stack: Vec<usize>,
    /// Included files read to the end whose text is still held.
    finished: Vec<usize>,
    peeked: Option<Token>,
}

impl<'t> Lexer<'t> {
    /// A lexer over `text`, which was read from `file`; `dir` is the
    /// file's folder relative to the main scene file's.
    pub fn new(file: Arc<Path>, text: &'t str, dir: Arc<Path>) -> Lexer<'t> {
        Lexer {
            sources: vec![Source::new(file, Cow::Borrowed(text), dir, None, 0)],
            stack: vec![0],
            finished: Vec::new(),
            peeked: None,
        }
    }

    /// Continues with the tokens of `text` (an included file, read from
    /// `file`, whose canonical path is `canonical`), then with those that
    /// follow in the files already open.
    pub fn include(&mut self, file: Arc<Path>, text: String, dir: Arc<Path>, canonical: PathBuf) {
        let last = self.sources.last().expect("a lexer has its main file");
        let base = last.base + last.len + 1;
        self.sources
            .push(Source::new(file, Cow::Owned(text), dir, Some(canonical), base));
        // A token already looked at comes after the included ones: the
        // file it came from (the innermost one) is read again from there.
        if let Some(t) = self.peeked.take() {
            if let Some(&top) = self.stack.last() {
                let s = &mut self.sources[top];
                s.pos = t.offset - s.base;
            }
        }
        self.stack.push(self.sources.len() - 1);
    }

    /// The canonical paths of the included files still being read,
    /// outermost first.
    pub fn open_includes(&self) -> impl Iterator<Item = &PathBuf> {
        self.stack.iter().filter_map(|&i| self.sources[i].canonical.as_ref())
    }

    /// Frees the text of included files that have been read to the end.
    /// Positions in them cannot be computed afterwards, so the parser calls
    /// this between directives.
    pub fn release(&mut self) {
        for i in self.finished.drain(..) {
            let s = &mut self.sources[i];
            s.released = true;
            s.text = Cow::Owned(String::new());
            s.line_starts = Vec::new();
        }
    }

    fn source_of(&self, offset: usize) -> &Source<'t> {
        let i = self.sources.partition_point(|s| s.base <= offset).max(1) - 1;
        &self.sources[i]
    }

    /// The position of `offset`.
    pub fn loc(&self, offset: usize) -> SourceLoc {
        let s = self.source_of(offset);
        s.loc(offset - s.base)
    }

    /// The folder (relative to the main file's) of the file that holds
    /// `offset`.
    pub fn dir_of(&self, offset: usize) -> Arc<Path> {
        self.source_of(offset).dir.clone()
    }

    /// The position just past the last character of the lexer's first file
    /// (for "unexpected end of file").
    pub fn end_loc(&self) -> SourceLoc {
        self.sources[0].loc(self.sources[0].len)
    }

    /// A syntax error at `offset`.
    pub fn error(&self, offset: usize, message: impl Into<String>) -> Error {
        Error::Scene {
            loc: Some(self.loc(offset)),
            key: None,
            message: message.into(),
        }
    }

    /// The next token without consuming it.
    pub fn peek(&mut self) -> Result<Option<&Token>> {
        if self.peeked.is_none() {
            self.peeked = self.scan()?;
        }
        Ok(self.peeked.as_ref())
    }

    /// The next token, or `None` at the end of the first file.
    #[allow(clippy::should_implement_trait)]
    pub fn next(&mut self) -> Result<Option<Token>> {
        match self.peeked.take() {
            Some(t) => Ok(Some(t)),
            None => self.scan(),
        }
    }

    /// The next token of the innermost open file; at its end, that file is
    /// closed and the one that included it continues.
    fn scan(&mut self) -> Result<Option<Token>> {
        while let Some(&i) = self.stack.last() {
            let s = &mut self.sources[i];
            let base = s.base;
            let Source { text, pos, .. } = s;
            match scan_one(text, pos) {
                Ok(Some((tok, start))) => {
                    return Ok(Some(Token {
                        tok,
                        offset: base + start,
                    }));
                }
                Ok(None) => {
                    self.stack.pop();
                    // The lexer's own file is borrowed: nothing to free.
                    if i > 0 {
                        self.finished.push(i);
                    }
                }
                Err((at, message)) => return Err(self.error(base + at, message)),
            }
        }
        Ok(None)
    }
}

/// The next token of `text` from `*pos`, and its offset in `text`; errors
/// are an offset in `text` and a message.
fn scan_one(text: &str, pos: &mut usize) -> std::result::Result<Option<(Tok, usize)>, (usize, String)> {
    let bytes = text.as_bytes();
    loop {
        let Some(&c) = bytes.get(*pos) else {
            return Ok(None);
        };
        let start = *pos;
        match c {
            b' ' | b'\t' | b'\n' | b'\r' | 0x0b | 0x0c => *pos += 1,
            b'#' => {
                while *pos < bytes.len() && bytes[*pos] != b'\n' && bytes[*pos] != b'\r' {
                    *pos += 1;
                }
            }
            b'[' | b']' => {
                *pos += 1;
                let tok = if c == b'[' { Tok::Open } else { Tok::Close };
                return Ok(Some((tok, start)));
            }
            b'"' => return string(text, pos, start).map(|t| Some((t, start))),
            _ => {
                while *pos < bytes.len()
                    && !matches!(
                        bytes[*pos],
                        b' ' | b'\t' | b'\n' | b'\r' | 0x0b | 0x0c | b'"' | b'[' | b']'
                    )
                {
                    *pos += 1;
                }
                return Ok(Some((Tok::Word(Word::new(&text[start..*pos])), start)));
            }
        }
    }
}

/// A quoted string starting at byte `start` of `text`. Strings end on the
/// same line; the escapes are those of pbrt-v4's `decodeEscaped`.
fn string(text: &str, pos: &mut usize, start: usize) -> std::result::Result<Tok, (usize, String)> {
    let bytes = text.as_bytes();
    *pos = start + 1;
    let mut decoded = String::new();
    let mut run_start = *pos;
    loop {
        let Some(&c) = bytes.get(*pos) else {
            return Err((
                start,
                "unterminated string: the file ends before its closing quote".into(),
            ));
        };
        match c {
            b'"' => {
                decoded.push_str(&text[run_start..*pos]);
                *pos += 1;
                return Ok(Tok::Str(decoded));
            }
            b'\n' | b'\r' => {
                return Err((
                    start,
                    "unterminated string: the line ends before its closing quote".into(),
                ));
            }
            b'\\' => {
                decoded.push_str(&text[run_start..*pos]);
                let escaped = match bytes.get(*pos + 1) {
                    Some(b'b') => '\u{8}',
                    Some(b'f') => '\u{c}',
                    Some(b'n') => '\n',
                    Some(b'r') => '\r',
                    Some(b't') => '\t',
                    Some(b'\\') => '\\',
                    Some(b'\'') => '\'',
                    Some(b'"') => '"',
                    None => return Err((start, "unterminated string: the file ends after `\\`".into())),
                    Some(_) => {
                        let ch = text[*pos + 1..].chars().next().unwrap_or('?');
                        return Err((
                            *pos,
                            format!("unknown escape `\\{ch}` in a string (known: \\b \\f \\n \\r \\t \\\\ \\' \\\")"),
                        ));
                    }
                };
                decoded.push(escaped);
                *pos += 2;
                run_start = *pos;
            }
            _ => *pos += 1,
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn lexer(text: &str) -> Lexer<'_> {
        Lexer::new(Arc::from(Path::new("t.pbrt")), text, Arc::from(Path::new("")))
    }

    fn word(w: &str) -> Tok {
        Tok::Word(Word::new(w))
    }

    fn tokens(text: &str) -> Result<Vec<Tok>> {
        let mut lx = lexer(text);
        let mut out = Vec::new();
        while let Some(t) = lx.next()? {
            out.push(t.tok);
        }
        Ok(out)
    }

    #[test]
    fn splits_words_strings_brackets_and_comments() {
        let t = tokens("Shape \"sphere\" \"float radius\"[2.5]# comment \"not a string\"\nWorldBegin").unwrap();
        assert_eq!(
            t,
            vec![
                word("Shape"),
                Tok::Str("sphere".into()),
                Tok::Str("float radius".into()),
                Tok::Open,
                word("2.5"),
                Tok::Close,
                word("WorldBegin"),
            ]
        );
    }

    #[test]
    fn decodes_escapes() {
        let t = tokens(r#""a\"b\\c\td""#).unwrap();
        assert_eq!(t, vec![Tok::Str("a\"b\\c\td".into())]);
    }

    #[test]
    fn bad_strings_are_errors_with_positions() {
        let e = tokens("Shape\n  \"sphere").unwrap_err().to_string();
        assert!(e.starts_with("t.pbrt:2:3: unterminated string"), "{e}");
        let e = tokens("\"a\nb\"").unwrap_err().to_string();
        assert!(e.starts_with("t.pbrt:1:1: unterminated string"), "{e}");
        let e = tokens("x \"a\\qb\"").unwrap_err().to_string();
        assert!(e.starts_with("t.pbrt:1:5: unknown escape `\\q`"), "{e}");
    }

    #[test]
    fn positions_count_characters() {
        let lx = lexer("é x\n  y");
        let l = lx.loc(3);
        assert_eq!((l.line, l.column), (1, 3));
        let l = lx.loc(7);
        assert_eq!((l.line, l.column), (2, 3));
        assert_eq!(lx.end_loc().line, 2);
    }
}
