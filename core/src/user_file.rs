//! Files a user names (maps, plans, models, settings, reconstructions,
//! calibrations, keep-out zones, photos), read whole: refused before they
//! are opened when they are not regular files, since opening a named pipe
//! waits for a writer for ever and a device never ends.

use std::io;
use std::path::Path;

/// Ok where `path` is a regular file (links followed); else an error that
/// says what it is instead.
pub fn check(path: &Path) -> io::Result<()> {
    let kind = std::fs::metadata(path)?.file_type();
    if kind.is_file() {
        return Ok(());
    }
    Err(io::Error::new(
        io::ErrorKind::InvalidInput,
        if kind.is_dir() {
            "it is a directory, not a file"
        } else {
            "it is not a regular file but a pipe, socket or device"
        },
    ))
}

/// `std::fs::read`, after [`check`].
pub fn read(path: &Path) -> io::Result<Vec<u8>> {
    check(path)?;
    std::fs::read(path)
}

/// `std::fs::read_to_string`, after [`check`].
pub fn read_to_string(path: &Path) -> io::Result<String> {
    check(path)?;
    std::fs::read_to_string(path)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_pipe_or_a_folder_is_refused_before_it_is_opened() {
        let dir = tempfile::tempdir().unwrap();
        let pipe = dir.path().join("map.ply");
        let made = std::process::Command::new("mkfifo")
            .arg(&pipe)
            .status()
            .unwrap();
        assert!(made.success());
        // Opening it would wait for a writer for ever: this returns at once.
        let err = read(&pipe).unwrap_err().to_string();
        assert!(err.contains("pipe, socket or device"), "{err}");
        let err = read_to_string(dir.path()).unwrap_err().to_string();
        assert!(err.contains("directory"), "{err}");
        std::fs::write(dir.path().join("plan.json"), "{}").unwrap();
        assert_eq!(read_to_string(&dir.path().join("plan.json")).unwrap(), "{}");
    }
}
