//! One process per run folder: every problem's runner takes its folder's lock first.

use std::fs::{File, TryLockError};
use std::path::Path;

use crate::error::IoContext;

/// The lock file a run holds in its folder while it writes there.
pub const LOCK_FILE: &str = ".ifslab.lock";

/// A run folder held by this process ([`lock_run_dir`]).
#[derive(Debug)]
pub struct RunLock {
    /// Holds the lock while open.
    file: File,
    dir: std::path::PathBuf,
    created: bool,
}

impl Drop for RunLock {
    /// A folder this lock created and nothing else wrote (a run refused at its start) is
    /// removed with it: a failed start leaves no folder behind.
    fn drop(&mut self) {
        if !self.created {
            return;
        }
        let only_lock = std::fs::read_dir(&self.dir).is_ok_and(|d| {
            d.filter_map(Result::ok)
                .all(|e| e.file_name() == std::ffi::OsStr::new(LOCK_FILE))
        });
        if only_lock {
            let _ = std::fs::remove_file(self.dir.join(LOCK_FILE));
            let _ = std::fs::remove_dir(&self.dir);
        }
    }
}

/// Takes the run folder `dir` for this process (creating it): a second process started on
/// the same folder is refused instead of writing it too. The lock is an advisory `flock` on
/// `dir/.ifslab.lock`, released when the returned guard is dropped or the process ends,
/// however it ends.
pub fn lock_run_dir(dir: &Path) -> crate::Result<RunLock> {
    let created = !dir.exists();
    std::fs::create_dir_all(dir).doing("creating", dir)?;
    let path = dir.join(LOCK_FILE);
    let file = File::options()
        .create(true)
        .truncate(false)
        .write(true)
        .open(&path)
        .doing("opening", &path)?;
    let lock = RunLock {
        file,
        dir: dir.to_path_buf(),
        created,
    };
    match lock.file.try_lock() {
        Ok(()) => Ok(lock),
        Err(TryLockError::WouldBlock) => {
            // Not ours to clean up: the other process's folder.
            let mut lock = lock;
            lock.created = false;
            Err(crate::Error::Locked {
                path: dir.to_path_buf(),
                message: format!(
                    "another ifslab process is writing {} (it holds {LOCK_FILE}); wait for it \
                     to end, or choose another output folder",
                    dir.display()
                ),
            })
        }
        Err(TryLockError::Error(e)) => Err(e).doing("locking", &path),
    }
}
