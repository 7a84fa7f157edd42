//! NFF's words and numbers: the file read in chunks of whole lines through one reused
//! buffer, each token with its line and column for messages, numbers parsed without
//! allocating ([`fast_f32`], with the standard parser as the fallback).

use super::super::SceneError;
use super::super::limits::MAX_LINE;
use std::io::BufRead;

/// The NFF entities.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub(super) enum Cmd {
    View,
    Background,
    Light,
    Fill,
    Cone,
    Sphere,
    Polygon,
    Patch,
}

impl Cmd {
    pub(super) fn parse(word: &[u8]) -> Option<Cmd> {
        Some(match word {
            b"v" => Cmd::View,
            b"b" => Cmd::Background,
            b"l" => Cmd::Light,
            b"f" => Cmd::Fill,
            b"c" => Cmd::Cone,
            b"s" => Cmd::Sphere,
            b"p" => Cmd::Polygon,
            b"pp" => Cmd::Patch,
            _ => return None,
        })
    }

    pub(super) fn name(self) -> &'static str {
        match self {
            Cmd::View => "v",
            Cmd::Background => "b",
            Cmd::Light => "l",
            Cmd::Fill => "f",
            Cmd::Cone => "c",
            Cmd::Sphere => "s",
            Cmd::Polygon => "p",
            Cmd::Patch => "pp",
        }
    }
}

/// The labels inside a `v` entity.
pub(super) const VIEW_LABELS: [&[u8]; 6] = [b"from", b"at", b"up", b"angle", b"hither", b"resolution"];

/// A word that starts an entity or a `v` line: met where a number was expected, it
/// means numbers are missing rather than that one is malformed.
pub(super) fn is_keyword(word: &[u8]) -> bool {
    Cmd::parse(word).is_some() || VIEW_LABELS.contains(&word)
}

/// A token of the current line: its byte range in the lexer's buffer and where it
/// starts in the file.
#[derive(Clone, Copy, Debug)]
pub(super) struct Tok {
    start: usize,
    end: usize,
    pub(super) line: usize,
    column: usize,
}

impl Tok {
    pub(super) fn column(&self) -> usize {
        self.column
    }
}

/// Bytes read from the input at a time; lines are found inside the chunk, not copied
/// out one by one (which took a tenth of the time to read a scene of triangles).
pub(super) const CHUNK: usize = 1 << 16;

/// Whitespace-separated tokens, line by line, over a buffer of whole lines read a chunk
/// at a time: memory stays at a chunk (or the longest line) whatever the file's size.
pub(super) struct Lexer<R> {
    input: R,
    /// Input read but not yet lexed past: `buf[..filled]`, whose lines from `next` on
    /// are still to come.
    buf: Vec<u8>,
    filled: usize,
    /// Where the current line starts, where its content ends (before any `#` comment
    /// or the line break) and where the next line starts.
    start: usize,
    end: usize,
    next: usize,
    pos: usize,
    pub(super) line: usize,
    pub(super) bytes: u64,
    eof: bool,
}

impl<R: BufRead> Lexer<R> {
    pub(super) fn new(input: R) -> Self {
        Lexer {
            input,
            buf: vec![0; CHUNK],
            filled: 0,
            start: 0,
            end: 0,
            next: 0,
            pos: 0,
            line: 0,
            bytes: 0,
            eof: false,
        }
    }

    /// The next token, not consumed; `None` at the end of the input. Stays valid until
    /// [`Lexer::bump`] and the next `peek`.
    pub(super) fn peek(&mut self, name: &str) -> Result<Option<Tok>, SceneError> {
        loop {
            while self.pos < self.end && self.buf[self.pos].is_ascii_whitespace() {
                self.pos += 1;
            }
            if self.pos < self.end {
                let start = self.pos;
                let mut end = start;
                while end < self.end && !self.buf[end].is_ascii_whitespace() {
                    end += 1;
                }
                return Ok(Some(Tok { start, end, line: self.line, column: start - self.start + 1 }));
            }
            if !self.next_line(name)? {
                return Ok(None);
            }
        }
    }

    /// Moves to the next line, reading more input when the buffer holds no whole line;
    /// `false` at the end of the input. A line past [`MAX_LINE`] is an error.
    pub(super) fn next_line(&mut self, name: &str) -> Result<bool, SceneError> {
        if self.next_line_read() {
            return Ok(true);
        }
        // No whole line left in the buffer: read until there is one.
        let end = loop {
            if self.filled - self.next > MAX_LINE {
                return Err(SceneError::At {
                    file: name.to_owned(),
                    line: self.line + 1,
                    column: 1,
                    field: "line".to_owned(),
                    message: format!("longer than {} MiB: not a text file of this format?", MAX_LINE >> 20),
                });
            }
            if self.eof {
                if self.next == self.filled {
                    return Ok(false);
                }
                break self.filled; // a last line without a line break
            }
            // Keep the partial line, read more after it.
            self.buf.copy_within(self.next..self.filled, 0);
            (self.filled, self.next) = (self.filled - self.next, 0);
            if self.filled == self.buf.len() {
                self.buf.resize(self.buf.len() * 2, 0);
            }
            let chunk = self.input.fill_buf().map_err(|e| SceneError::File {
                file: name.to_owned(),
                message: format!("cannot read line {}: {e}", self.line + 1),
            })?;
            let n = chunk.len().min(self.buf.len() - self.filled);
            self.buf[self.filled..self.filled + n].copy_from_slice(&chunk[..n]);
            self.input.consume(n);
            self.filled += n;
            self.eof = n == 0;
            if let Some(i) = memchr::memchr(b'\n', &self.buf[self.next..self.filled]) {
                break self.next + i + 1;
            }
        };
        self.enter_line(end);
        Ok(true)
    }

    /// Moves to the next line if the buffer holds all of it already (no reading, so no
    /// error): `false` if not.
    #[inline(always)]
    pub(super) fn next_line_read(&mut self) -> bool {
        match memchr::memchr(b'\n', &self.buf[self.next..self.filled]) {
            Some(i) => {
                self.enter_line(self.next + i + 1);
                true
            }
            None => false,
        }
    }

    /// Makes the line from `next` to `end` the current one.
    #[inline(always)]
    pub(super) fn enter_line(&mut self, end: usize) {
        (self.start, self.pos, self.next) = (self.next, self.next, end);
        self.end = memchr::memchr(b'#', &self.buf[self.start..end]).map_or(end, |i| self.start + i);
        self.line += 1;
        self.bytes += (end - self.start) as u64;
    }

    /// The next token as a number, consumed, where that is quick to tell: it is on the
    /// current line and [`fast_f32`] reads it (nearly every number of a real file).
    /// Else `None`, and nothing consumed. Reading a scene of triangles spent a quarter
    /// of its time getting numbers through [`Lexer::peek`] before this.
    #[inline(always)]
    pub(super) fn quick_number(&mut self) -> Option<f32> {
        let mut at = self.pos;
        loop {
            while at < self.end && self.buf[at].is_ascii_whitespace() {
                at += 1;
            }
            if at < self.end {
                break;
            }
            // The line is used up: go on to the next if it is in the buffer already.
            if !self.next_line_read() {
                self.pos = at;
                return None;
            }
            at = self.pos;
        }
        // Read in the one pass that finds the token's end: the number must end it.
        let line = &self.buf[at..self.end];
        let (x, len) = number_prefix(line)?;
        if line.get(len).is_some_and(|c| !c.is_ascii_whitespace()) {
            return None;
        }
        self.pos = at + len;
        Some(x)
    }

    pub(super) fn bump(&mut self, tok: Tok) {
        self.pos = tok.end;
    }

    pub(super) fn text(&self, tok: Tok) -> &[u8] {
        &self.buf[tok.start..tok.end]
    }
}

/// A token as it appears in messages: lossy, and shortened.
pub(super) fn show(word: &[u8]) -> String {
    let s = String::from_utf8_lossy(word);
    if s.chars().count() > 24 { format!("{}...", s.chars().take(24).collect::<String>()) } else { s.into_owned() }
}

pub(super) fn parse_f32(word: &[u8]) -> Option<f32> {
    fast_f32(word).or_else(|| std::str::from_utf8(word).ok()?.parse().ok())
}

/// Powers of ten that are exact in f32.
pub(super) const POW10: [f32; 11] = [1e0, 1e1, 1e2, 1e3, 1e4, 1e5, 1e6, 1e7, 1e8, 1e9, 1e10];

/// Clinger's fast path: a decimal whose digits fit in 24 bits, scaled by at most 10^10
/// either way, is one exactly represented integer times or over one exact power of
/// ten, so a single correctly rounded f32 operation gives the same value as the full
/// parser. Numbers written with `%g` (six digits) nearly all qualify; anything else
/// (`None`) goes to `str::parse`.
#[inline(always)]
pub(super) fn fast_f32(w: &[u8]) -> Option<f32> {
    number_prefix(w).and_then(|(x, len)| (len == w.len()).then_some(x))
}

/// [`fast_f32`] of the number `w` starts with, and how many bytes it takes: `None` if
/// it starts with none the fast path reads, whatever follows.
#[inline(always)]
fn number_prefix(w: &[u8]) -> Option<(f32, usize)> {
    let (negative, mut i) = match w.first()? {
        b'-' => (true, 1),
        b'+' => (false, 1),
        _ => (false, 0),
    };
    let (mut m, mut exp, mut digits) = (0u32, 0i32, 0);
    // The mantissa only grows, so it fails as soon as it passes 2^24 (and, at most ten
    // times that plus nine, cannot overflow first).
    let mut digit = |c: u8, m: &mut u32| -> Option<()> {
        *m = *m * 10 + (c - b'0') as u32;
        digits += 1;
        (*m <= 1 << 24).then_some(())
    };
    while i < w.len() && w[i].is_ascii_digit() {
        digit(w[i], &mut m)?;
        i += 1;
    }
    if i < w.len() && w[i] == b'.' {
        i += 1;
        while i < w.len() && w[i].is_ascii_digit() {
            digit(w[i], &mut m)?;
            exp -= 1;
            i += 1;
        }
    }
    if digits == 0 {
        return None;
    }
    if i < w.len() && (w[i] == b'e' || w[i] == b'E') {
        i += 1;
        let sign = match w.get(i) {
            Some(b'-') => {
                i += 1;
                -1
            }
            Some(b'+') => {
                i += 1;
                1
            }
            _ => 1,
        };
        let start = i;
        let mut e = 0i32;
        while i < w.len() && w[i].is_ascii_digit() && i - start < 4 {
            e = e * 10 + (w[i] - b'0') as i32;
            i += 1;
        }
        if i == start {
            return None;
        }
        exp += sign * e;
    }
    if !(-10..=10).contains(&exp) {
        return None;
    }
    let x = if exp >= 0 { m as f32 * POW10[exp as usize] } else { m as f32 / POW10[(-exp) as usize] };
    Some((if negative { -x } else { x }, i))
}
