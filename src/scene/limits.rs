//! What the readers refuse before they start: files that are not regular files (a
//! device such as /dev/zero, a pipe, a folder), lines longer than [`MAX_LINE`], and text
//! that is not UTF-8. Each refusal names the file and, where there is one, the line.

use super::SceneError;
use std::io::BufRead;
use std::path::Path;

/// Longest line the NFF and OBJ readers accept, in bytes. Real files stay far below it
/// (gears.nff's longest is about 5 KB); past it the input is taken to be binary data.
pub const MAX_LINE: usize = 1 << 20;

/// Opens `path` for reading if it is a regular file. `what` says what it should be
/// ("scene", "mesh").
pub fn open_regular(path: &Path, what: &str) -> Result<std::fs::File, SceneError> {
    let file_err = |message: String| SceneError::File { file: path.display().to_string(), message };
    let file = std::fs::File::open(path).map_err(|e| file_err(format!("cannot read the {what}: {e}")))?;
    let meta = file.metadata().map_err(|e| file_err(format!("cannot read the {what}: {e}")))?;
    if !meta.is_file() {
        let kind = if meta.is_dir() { "a folder" } else { "not a regular file (a device or a pipe?)" };
        return Err(file_err(format!("cannot read the {what}: it is {kind}")));
    }
    Ok(file)
}

/// Reads one line (with its `\n`) into `buf`, appending; returns the bytes read (0 at
/// the end). A line past [`MAX_LINE`] is an error naming `name` and line `number`.
pub fn read_line(input: &mut impl BufRead, buf: &mut Vec<u8>, name: &str, number: usize) -> Result<usize, SceneError> {
    let start = buf.len();
    loop {
        let chunk = input.fill_buf().map_err(|e| SceneError::File {
            file: name.to_owned(),
            message: format!("cannot read line {number}: {e}"),
        })?;
        if chunk.is_empty() {
            return Ok(buf.len() - start);
        }
        let (take, done) = match chunk.iter().position(|&b| b == b'\n') {
            Some(i) => (i + 1, true),
            None => (chunk.len(), false),
        };
        buf.extend_from_slice(&chunk[..take]);
        input.consume(take);
        if buf.len() - start > MAX_LINE {
            return Err(SceneError::At {
                file: name.to_owned(),
                line: number,
                column: 1,
                field: "line".to_owned(),
                message: format!("longer than {} MiB: not a text file of this format?", MAX_LINE >> 20),
            });
        }
        if done {
            return Ok(buf.len() - start);
        }
    }
}

/// The text of a file, or an error naming the line where it stops being UTF-8.
pub fn utf8(bytes: Vec<u8>, name: &str) -> Result<String, SceneError> {
    String::from_utf8(bytes).map_err(|e| {
        let bad = e.utf8_error().valid_up_to();
        let bytes = e.as_bytes();
        let line = bytes[..bad].iter().filter(|&&b| b == b'\n').count() + 1;
        let column = bad - bytes[..bad].iter().rposition(|&b| b == b'\n').map_or(0, |i| i + 1) + 1;
        SceneError::At {
            file: name.to_owned(),
            line,
            column,
            field: "text".to_owned(),
            message: "not UTF-8 text (binary data, or another encoding)".to_owned(),
        }
    })
}

/// A word from the input as it appears in messages: lossy and shortened, so that a
/// 4-million-character keyword is not echoed whole.
pub fn show(word: &str) -> String {
    if word.chars().count() > 40 {
        format!("{}...", word.chars().take(40).collect::<String>())
    } else {
        word.to_owned()
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn devices_long_lines_and_bad_text_are_refused() {
        #[cfg(unix)]
        assert!(open_regular(Path::new("/dev/zero"), "scene").unwrap_err().to_string().contains("not a regular file"));
        assert!(open_regular(Path::new("."), "scene").unwrap_err().to_string().contains("a folder"));
        let long = vec![b'x'; MAX_LINE + 10];
        let mut input = std::io::Cursor::new(long);
        let e = read_line(&mut input, &mut Vec::new(), "f.obj", 1).unwrap_err().to_string();
        assert!(e.starts_with("f.obj:1:1: line: longer than"), "{e}");
        let mut input = std::io::Cursor::new(b"ab\ncd".to_vec());
        let mut buf = Vec::new();
        assert_eq!(read_line(&mut input, &mut buf, "f", 1).unwrap(), 3);
        assert_eq!(read_line(&mut input, &mut buf, "f", 2).unwrap(), 2);
        assert_eq!(buf, b"ab\ncd");
        let e = utf8(b"a = 1\nb = \"\xff\"\n".to_vec(), "s.toml").unwrap_err().to_string();
        assert!(e.starts_with("s.toml:2:6: text: not UTF-8"), "{e}");
        assert_eq!(show(&"k".repeat(4_000_000)).len(), 43);
    }
}
