/// A scene that cannot be used, and where the problem is.
#[derive(Clone, Debug, PartialEq, thiserror::Error)]
pub enum SceneError {
    /// A problem at a place in a file: `room.toml:12:10: radius: must be > 0 (got -1)`.
    #[error("{file}:{line}:{column}: {field}: {message}")]
    At { file: String, line: usize, column: usize, field: String, message: String },
    /// A problem with a file as a whole (it cannot be read).
    #[error("{file}: {message}")]
    File { file: String, message: String },
}
