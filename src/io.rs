//! File helpers shared by every writer: atomic writes so a crash never leaves a half file.

use std::io::Write;
use std::path::Path;

use crate::error::{Error, Result};

/// Writes `bytes` to `path` atomically: a temporary file in the same folder is written,
/// flushed to disk and renamed over the destination. When any step fails (a full disk, a
/// folder that cannot be written) the temporary file is removed, the previous file at `path`
/// is left as it was, and the error names `path` (and, for a full disk, says so).
pub fn write_atomic(path: &Path, bytes: &[u8]) -> Result<()> {
    write_atomic_with(path, bytes, |tmp| std::fs::File::create(tmp))
}

/// [`write_atomic`] with the temporary file opened by `create` (tests inject failing
/// writers here: `/dev/full`, a writer that stops half-way).
fn write_atomic_with<W: Write + SyncAll>(
    path: &Path,
    bytes: &[u8],
    create: impl FnOnce(&Path) -> std::io::Result<W>,
) -> Result<()> {
    let dir = match path.parent() {
        Some(d) if !d.as_os_str().is_empty() => d,
        _ => Path::new("."),
    };
    std::fs::create_dir_all(dir).map_err(|e| Error::io(dir, e))?;
    let file_name = path
        .file_name()
        .map(|n| n.to_string_lossy().into_owned())
        .unwrap_or_else(|| "out".into());
    let tmp = dir.join(format!(".{file_name}.{}.tmp", std::process::id()));
    let result = (|| {
        let mut f = create(&tmp)?;
        f.write_all(bytes)?;
        f.sync_all()?;
        drop(f);
        std::fs::rename(&tmp, path)
    })();
    result.map_err(|e| {
        let _ = std::fs::remove_file(&tmp);
        if e.kind() == std::io::ErrorKind::StorageFull {
            Error::io(
                path,
                std::io::Error::new(
                    e.kind(),
                    format!("{e}: the disk is full; free some space or write elsewhere (nothing was overwritten)"),
                ),
            )
        } else {
            Error::io(path, e)
        }
    })
}

/// Flushing a file's data to the disk.
trait SyncAll {
    fn sync_all(&mut self) -> std::io::Result<()>;
}

impl SyncAll for std::fs::File {
    fn sync_all(&mut self) -> std::io::Result<()> {
        std::fs::File::sync_all(self)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A file that takes `left` bytes and then reports a full disk.
    struct FillsUp {
        file: std::fs::File,
        left: usize,
    }

    impl Write for FillsUp {
        fn write(&mut self, buf: &[u8]) -> std::io::Result<usize> {
            if self.left == 0 {
                return Err(std::io::ErrorKind::StorageFull.into());
            }
            let n = buf.len().min(self.left);
            self.left -= n;
            self.file.write(&buf[..n])
        }
        fn flush(&mut self) -> std::io::Result<()> {
            self.file.flush()
        }
    }

    impl SyncAll for FillsUp {
        fn sync_all(&mut self) -> std::io::Result<()> {
            self.file.sync_all()
        }
    }

    fn leftovers(dir: &Path) -> Vec<String> {
        std::fs::read_dir(dir)
            .unwrap()
            .map(|e| e.unwrap().file_name().to_string_lossy().into_owned())
            .filter(|n| n.ends_with(".tmp"))
            .collect()
    }

    #[test]
    fn a_full_disk_half_way_leaves_the_previous_file_and_no_temporary_one() {
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("checkpoint.json");
        write_atomic(&path, b"{\"iteration\": 100}").unwrap();
        let err = write_atomic_with(&path, &[b'x'; 4096], |tmp| {
            Ok(FillsUp {
                file: std::fs::File::create(tmp)?,
                left: 1000,
            })
        })
        .unwrap_err()
        .to_string();
        assert!(
            err.contains("checkpoint.json") && err.contains("disk is full"),
            "{err}"
        );
        assert_eq!(std::fs::read(&path).unwrap(), b"{\"iteration\": 100}");
        assert!(
            leftovers(dir.path()).is_empty(),
            "{:?}",
            leftovers(dir.path())
        );
    }

    #[cfg(target_os = "linux")]
    #[test]
    fn the_kernels_full_device_is_reported_as_a_full_disk() {
        // Writes to /dev/full fail with ENOSPC, as on a disk with no space left.
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("code.json");
        write_atomic(&path, b"old").unwrap();
        let err = write_atomic_with(&path, &[0u8; 1 << 16], |_| {
            std::fs::OpenOptions::new().write(true).open("/dev/full")
        })
        .unwrap_err()
        .to_string();
        assert!(
            err.contains("code.json") && err.contains("disk is full"),
            "{err}"
        );
        assert_eq!(std::fs::read(&path).unwrap(), b"old");
    }
}
