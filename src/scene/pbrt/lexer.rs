//! Tokens of the pbrt-v4 scene format (pbrt-v4 file format documentation,
//! "General syntax"; `Tokenizer::Next` in pbrt-v4's parser.cpp): quoted
//! strings, `[` and `]`, `#` comments to the end of the line, and bare words
//! (directive names, numbers, `true`/`false`) that end at white space, a
//! quote or a bracket.

use crate::error::{Error, Result, SourceLoc};
use std::borrow::Cow;
use std::path::Path;
use std::sync::Arc;

/// What a token is.
#[derive(Clone, Debug, PartialEq)]
pub(crate) enum Tok<'t> {
    /// A bare word: a directive name, a number, `true` or `false`.
    Word(&'t str),
    /// A quoted string, without its quotes and with escapes decoded.
    Str(Cow<'t, str>),
    /// `[`
    Open,
    /// `]`
    Close,
}

/// A token and the byte offset where it starts.
#[derive(Clone, Debug, PartialEq)]
pub(crate) struct Token<'t> {
    /// The token.
    pub tok: Tok<'t>,
    /// Byte offset of its first character.
    pub offset: usize,
}

impl Token<'_> {
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

/// Splits one file's text into tokens and turns offsets into positions.
pub(crate) struct Lexer<'t> {
    file: Arc<Path>,
    text: &'t str,
    pos: usize,
    /// Byte offset of the start of each line, for offset → line lookups by
    /// binary search (files can have millions of lines).
    line_starts: Vec<usize>,
    peeked: Option<Token<'t>>,
}

impl<'t> Lexer<'t> {
    /// A lexer over `text`, which was read from `file`.
    pub fn new(file: Arc<Path>, text: &'t str) -> Lexer<'t> {
        let mut line_starts = vec![0];
        line_starts.extend(text.match_indices('\n').map(|(i, _)| i + 1));
        Lexer {
            file,
            text,
            pos: 0,
            line_starts,
            peeked: None,
        }
    }

    /// The position of byte `offset`.
    pub fn loc(&self, offset: usize) -> SourceLoc {
        let offset = offset.min(self.text.len());
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

    /// The position just past the last character (for "unexpected end of
    /// file").
    pub fn end_loc(&self) -> SourceLoc {
        self.loc(self.text.len())
    }

    /// A syntax error at byte `offset`.
    pub fn error(&self, offset: usize, message: impl Into<String>) -> Error {
        Error::Scene {
            loc: Some(self.loc(offset)),
            key: None,
            message: message.into(),
        }
    }

    /// The next token without consuming it.
    pub fn peek(&mut self) -> Result<Option<&Token<'t>>> {
        if self.peeked.is_none() {
            self.peeked = self.scan()?;
        }
        Ok(self.peeked.as_ref())
    }

    /// The next token, or `None` at the end of the file.
    #[allow(clippy::should_implement_trait)]
    pub fn next(&mut self) -> Result<Option<Token<'t>>> {
        match self.peeked.take() {
            Some(t) => Ok(Some(t)),
            None => self.scan(),
        }
    }

    fn scan(&mut self) -> Result<Option<Token<'t>>> {
        let bytes = self.text.as_bytes();
        loop {
            let Some(&c) = bytes.get(self.pos) else {
                return Ok(None);
            };
            let start = self.pos;
            match c {
                b' ' | b'\t' | b'\n' | b'\r' | 0x0b | 0x0c => self.pos += 1,
                b'#' => {
                    while self.pos < bytes.len() && bytes[self.pos] != b'\n' && bytes[self.pos] != b'\r' {
                        self.pos += 1;
                    }
                }
                b'[' | b']' => {
                    self.pos += 1;
                    let tok = if c == b'[' { Tok::Open } else { Tok::Close };
                    return Ok(Some(Token { tok, offset: start }));
                }
                b'"' => return self.string(start).map(Some),
                _ => {
                    while self.pos < bytes.len()
                        && !matches!(
                            bytes[self.pos],
                            b' ' | b'\t' | b'\n' | b'\r' | 0x0b | 0x0c | b'"' | b'[' | b']'
                        )
                    {
                        self.pos += 1;
                    }
                    return Ok(Some(Token {
                        tok: Tok::Word(&self.text[start..self.pos]),
                        offset: start,
                    }));
                }
            }
        }
    }

    /// A quoted string starting at `start`. Strings end on the same line;
    /// the escapes are those of pbrt-v4's `decodeEscaped`.
    fn string(&mut self, start: usize) -> Result<Token<'t>> {
        let bytes = self.text.as_bytes();
        self.pos = start + 1;
        let mut decoded: Option<String> = None;
        let mut run_start = self.pos;
        loop {
            let Some(&c) = bytes.get(self.pos) else {
                return Err(self.error(start, "unterminated string: the file ends before its closing quote"));
            };
            match c {
                b'"' => {
                    let tok = match decoded {
                        None => Tok::Str(Cow::Borrowed(&self.text[start + 1..self.pos])),
                        Some(mut s) => {
                            s.push_str(&self.text[run_start..self.pos]);
                            Tok::Str(Cow::Owned(s))
                        }
                    };
                    self.pos += 1;
                    return Ok(Token { tok, offset: start });
                }
                b'\n' | b'\r' => {
                    return Err(self.error(start, "unterminated string: the line ends before its closing quote"));
                }
                b'\\' => {
                    let s = decoded.get_or_insert_with(String::new);
                    s.push_str(&self.text[run_start..self.pos]);
                    let escaped = match bytes.get(self.pos + 1) {
                        Some(b'b') => '\u{8}',
                        Some(b'f') => '\u{c}',
                        Some(b'n') => '\n',
                        Some(b'r') => '\r',
                        Some(b't') => '\t',
                        Some(b'\\') => '\\',
                        Some(b'\'') => '\'',
                        Some(b'"') => '"',
                        None => {
                            return Err(self.error(start, "unterminated string: the file ends after `\\`"));
                        }
                        Some(_) => {
                            let ch = self.text[self.pos + 1..].chars().next().unwrap_or('?');
                            return Err(self.error(
                                self.pos,
                                format!(
                                    "unknown escape `\\{ch}` in a string (known: \\b \\f \\n \\r \\t \\\\ \\' \\\")"
                                ),
                            ));
                        }
                    };
                    s.push(escaped);
                    self.pos += 2;
                    run_start = self.pos;
                }
                _ => self.pos += 1,
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn tokens(text: &str) -> Result<Vec<Tok<'_>>> {
        let mut lx = Lexer::new(Arc::from(Path::new("t.pbrt")), text);
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
                Tok::Word("Shape"),
                Tok::Str("sphere".into()),
                Tok::Str("float radius".into()),
                Tok::Open,
                Tok::Word("2.5"),
                Tok::Close,
                Tok::Word("WorldBegin"),
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
        let lx = Lexer::new(Arc::from(Path::new("t.pbrt")), "é x\n  y");
        let l = lx.loc(3);
        assert_eq!((l.line, l.column), (1, 3));
        let l = lx.loc(7);
        assert_eq!((l.line, l.column), (2, 3));
        assert_eq!(lx.end_loc().line, 2);
    }
}
