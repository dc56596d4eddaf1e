//! Atomic file writes: a file tfs writes is either the previous one or the complete new one,
//! never a truncated mix, whatever fails in between (a full disk, a killed process, an error
//! while the content is produced).
//!
//! The content goes to a temporary file in the target's own directory (a rename is atomic only
//! within one file system); the temporary file is flushed to disk (`fsync`), renamed over the
//! target, and the directory entry is flushed too. A temporary file left by an error is removed;
//! one left by a killed process is a hidden `.NAME.*.tmp.EXT` file beside the target.

use std::io::Write;
use std::path::{Path, PathBuf};
use std::sync::atomic::{AtomicU64, Ordering};

/// A file being written atomically: write to [`AtomicFile::temp_path`] (or through
/// [`AtomicFile::file`]), then [`AtomicFile::commit`]. Dropped without a commit, the temporary
/// file is removed and the target is left as it was.
#[derive(Debug)]
pub struct AtomicFile {
    target: PathBuf,
    temp: PathBuf,
    file: Option<std::fs::File>,
    committed: bool,
}

/// Makes temporary names unique within the process (threads may write beside each other).
static COUNTER: AtomicU64 = AtomicU64::new(0);

impl AtomicFile {
    /// Starts an atomic write of `target`: creates an empty temporary file beside it with the
    /// same extension (writers that choose a format by extension, like image encoders, work on
    /// it). A symbolic link as target is followed: the file it points to is replaced. The
    /// target's directory must exist; an existing target must pass [`check_target`] (a regular
    /// file that is not read-only).
    pub fn create(target: impl AsRef<Path>) -> std::io::Result<Self> {
        check_target(target.as_ref())?;
        let target = resolve_link(target.as_ref());
        let dir = match target.parent() {
            Some(d) if !d.as_os_str().is_empty() => d.to_path_buf(),
            _ => PathBuf::from("."),
        };
        let name = target
            .file_name()
            .map(|n| n.to_string_lossy().into_owned())
            .ok_or_else(|| {
                std::io::Error::new(
                    std::io::ErrorKind::InvalidInput,
                    "the path has no file name; give a file name",
                )
            })?;
        let ext = target
            .extension()
            .map(|e| format!(".{}", e.to_string_lossy()))
            .unwrap_or_default();
        let mut last = None;
        for _ in 0..16 {
            let n = COUNTER.fetch_add(1, Ordering::Relaxed);
            let temp = dir.join(format!(".{name}.{}-{n}.tmp{ext}", std::process::id()));
            match std::fs::OpenOptions::new()
                .write(true)
                .create_new(true)
                .open(&temp)
            {
                Ok(file) => {
                    // Keep the permissions of the file being replaced.
                    if let Ok(meta) = std::fs::metadata(&target) {
                        file.set_permissions(meta.permissions()).ok();
                    }
                    return Ok(Self {
                        target,
                        temp,
                        file: Some(file),
                        committed: false,
                    });
                }
                Err(e) if e.kind() == std::io::ErrorKind::AlreadyExists => last = Some(e),
                Err(e) => return Err(e),
            }
        }
        Err(last.unwrap_or_else(|| std::io::Error::other("no free temporary name")))
    }

    /// The temporary file the content goes to before [`AtomicFile::commit`].
    pub fn temp_path(&self) -> &Path {
        &self.temp
    }

    /// The file that will be replaced (a symbolic link already resolved).
    pub fn target(&self) -> &Path {
        &self.target
    }

    /// The open temporary file, for writing the content directly.
    pub fn file(&mut self) -> std::io::Result<&mut std::fs::File> {
        // Present from `create` until `commit` consumes self.
        self.file
            .as_mut()
            .ok_or_else(|| std::io::Error::other("the temporary file is closed"))
    }

    /// Flushes the temporary file to disk, renames it over the target and flushes the directory.
    /// On error the target is unchanged and the temporary file is removed.
    pub fn commit(mut self) -> std::io::Result<()> {
        // fsync flushes the file, whichever handle wrote it (an encoder that opened the
        // temporary path itself included).
        let f = self
            .file
            .take()
            .ok_or_else(|| std::io::Error::other("already committed"))?;
        f.sync_all()?;
        drop(f);
        std::fs::rename(&self.temp, &self.target)?;
        self.committed = true;
        if let Some(dir) = self.target.parent().filter(|d| !d.as_os_str().is_empty()) {
            // Best effort: the rename is durable once the directory is flushed; some file
            // systems refuse to open a directory for that and the data is still in place.
            if let Ok(d) = std::fs::File::open(dir) {
                d.sync_all().ok();
            }
        }
        Ok(())
    }
}

impl Drop for AtomicFile {
    fn drop(&mut self) {
        if !self.committed {
            drop(self.file.take());
            std::fs::remove_file(&self.temp).ok();
        }
    }
}

/// Checks that `target` may be replaced by an atomic write: it does not exist yet, or it is a
/// regular file (or a symbolic link to one) that is writable. A directory, a device node (like
/// `/dev/null` or `/dev/full`), a FIFO or a socket is refused — the rename would put a regular
/// file in its place — and so is a read-only file, which tfs keeps read-only as `cp` and editors
/// do (for every user, root included: the permission bits decide). The error says what to do.
pub fn check_target(target: &Path) -> std::io::Result<()> {
    use std::io::{Error, ErrorKind};
    let meta = match std::fs::metadata(target) {
        Ok(m) => m,
        Err(e) if e.kind() == ErrorKind::NotFound => return Ok(()),
        Err(e) => return Err(e),
    };
    let ft = meta.file_type();
    if ft.is_dir() {
        return Err(Error::new(
            ErrorKind::IsADirectory,
            "the path is a directory; give a file name",
        ));
    }
    if !ft.is_file() {
        return Err(Error::new(
            ErrorKind::InvalidInput,
            format!(
                "the path is {}, not a regular file; tfs writes its results only into regular files (it would replace the {} with one): give a file name",
                special_kind(&ft),
                special_kind(&ft).trim_start_matches("a ")
            ),
        ));
    }
    let read_only = meta.permissions().readonly()
        || matches!(
            std::fs::OpenOptions::new().write(true).open(target),
            Err(e) if e.kind() == ErrorKind::PermissionDenied
        );
    if read_only {
        return Err(Error::new(
            ErrorKind::PermissionDenied,
            "the file is read-only and tfs does not replace a read-only file; make it writable (chmod u+w) or choose another file name",
        ));
    }
    Ok(())
}

/// What kind of file a non-regular, non-directory file type is, for messages.
fn special_kind(ft: &std::fs::FileType) -> &'static str {
    #[cfg(unix)]
    {
        use std::os::unix::fs::FileTypeExt;
        if ft.is_char_device() {
            return "a character device";
        }
        if ft.is_block_device() {
            return "a block device";
        }
        if ft.is_fifo() {
            return "a FIFO (named pipe)";
        }
        if ft.is_socket() {
            return "a socket";
        }
    }
    let _ = ft;
    "a special file"
}

/// A set of files written atomically as a set: each is written completely to its temporary
/// file first, and only when every one is complete are they renamed over their targets. A
/// failure while any of them is produced or flushed leaves every previous file as it was
/// (the renames at the end are separate operations, each atomic).
#[derive(Debug, Default)]
pub struct AtomicSet {
    files: Vec<AtomicFile>,
}

impl AtomicSet {
    /// An empty set.
    pub fn new() -> Self {
        Self::default()
    }

    /// Writes `target`'s content to a temporary file with `write` (through a buffered writer);
    /// the target is replaced only by [`AtomicSet::commit`].
    pub fn add_with<F>(&mut self, target: impl AsRef<Path>, write: F) -> std::io::Result<()>
    where
        F: FnOnce(&mut dyn Write) -> std::io::Result<()>,
    {
        let mut af = AtomicFile::create(target)?;
        {
            let mut w = std::io::BufWriter::new(af.file()?);
            write(&mut w)?;
            w.flush()?;
        }
        af.file()?.sync_all()?;
        self.files.push(af);
        Ok(())
    }

    /// Renames every file of the set over its target (see [`AtomicFile::commit`]); returns the
    /// targets in the order they were added.
    pub fn commit(self) -> std::io::Result<Vec<PathBuf>> {
        let mut done = Vec::with_capacity(self.files.len());
        for af in self.files {
            done.push(af.target().to_path_buf());
            af.commit()?;
        }
        Ok(done)
    }
}

/// The file a symbolic link points to (relative links resolved against the link's directory);
/// other paths unchanged.
fn resolve_link(path: &Path) -> PathBuf {
    let mut p = path.to_path_buf();
    for _ in 0..32 {
        match std::fs::symlink_metadata(&p) {
            Ok(m) if m.file_type().is_symlink() => match std::fs::read_link(&p) {
                Ok(dest) if dest.is_absolute() => p = dest,
                Ok(dest) => p = p.parent().unwrap_or(Path::new(".")).join(dest),
                Err(_) => break,
            },
            _ => break,
        }
    }
    p
}

/// Writes `target` atomically with the content `write` produces through a buffered writer. If
/// `write` (or the disk) fails, the target keeps its previous content and the error is returned.
///
/// ```
/// let dir = std::env::temp_dir().join(format!("tfs-atomic-doc-{}", std::process::id()));
/// std::fs::create_dir_all(&dir).unwrap();
/// let p = dir.join("a.txt");
/// tfs_data::write_atomic(&p, b"old").unwrap();
/// let failed = tfs_data::write_atomic_with(&p, |w| {
///     w.write_all(b"half of the new")?;
///     Err(std::io::Error::other("the producer failed"))
/// });
/// assert!(failed.is_err());
/// assert_eq!(std::fs::read(&p).unwrap(), b"old");
/// std::fs::remove_dir_all(&dir).ok();
/// ```
pub fn write_atomic_with<F>(target: impl AsRef<Path>, write: F) -> std::io::Result<()>
where
    F: FnOnce(&mut dyn Write) -> std::io::Result<()>,
{
    let mut af = AtomicFile::create(target)?;
    {
        let mut w = std::io::BufWriter::new(af.file()?);
        write(&mut w)?;
        w.flush()?;
    }
    af.commit()
}

/// Writes `contents` to `target` atomically (see [`write_atomic_with`]); a drop-in for
/// `std::fs::write`.
pub fn write_atomic(target: impl AsRef<Path>, contents: impl AsRef<[u8]>) -> std::io::Result<()> {
    write_atomic_with(target, |w| w.write_all(contents.as_ref()))
}

#[cfg(test)]
mod tests {
    use super::*;

    fn temps(dir: &Path) -> Vec<String> {
        std::fs::read_dir(dir)
            .unwrap()
            .filter_map(|e| e.ok())
            .map(|e| e.file_name().to_string_lossy().into_owned())
            .filter(|n| n.contains(".tmp"))
            .collect()
    }

    #[test]
    fn replaces_content_and_leaves_no_temporary() {
        let dir = tempfile::tempdir().unwrap();
        let p = dir.path().join("m.json");
        write_atomic(&p, b"first").unwrap();
        write_atomic(&p, b"second").unwrap();
        assert_eq!(std::fs::read(&p).unwrap(), b"second");
        assert!(temps(dir.path()).is_empty());
    }

    /// An error while the content is produced leaves the previous file and no temporary.
    #[test]
    fn producer_error_keeps_previous_file() {
        let dir = tempfile::tempdir().unwrap();
        let p = dir.path().join("m.json");
        write_atomic(&p, b"good model").unwrap();
        let e = write_atomic_with(&p, |w| {
            w.write_all(&[b'x'; 100_000])?;
            Err(std::io::Error::other("simulated failure"))
        })
        .unwrap_err();
        assert_eq!(e.to_string(), "simulated failure");
        assert_eq!(std::fs::read(&p).unwrap(), b"good model");
        assert!(temps(dir.path()).is_empty(), "{:?}", temps(dir.path()));
    }

    /// A write to a file system that refuses more bytes (a full disk) keeps the previous file.
    #[cfg(target_os = "linux")]
    #[test]
    fn full_device_keeps_previous_file() {
        // /dev/full fails every write with ENOSPC: writing through it stands for a full disk.
        let dir = tempfile::tempdir().unwrap();
        let p = dir.path().join("m.json");
        write_atomic(&p, b"good model").unwrap();
        let e = write_atomic_with(&p, |w| {
            let mut full = std::fs::OpenOptions::new().write(true).open("/dev/full")?;
            let mut buf = Vec::new();
            buf.extend_from_slice(b"new model");
            w.write_all(&buf)?;
            full.write_all(&buf)
        })
        .unwrap_err();
        assert_eq!(e.raw_os_error(), Some(28), "{e}");
        assert_eq!(std::fs::read(&p).unwrap(), b"good model");
        assert!(temps(dir.path()).is_empty());
    }

    #[test]
    fn follows_a_symbolic_link_and_keeps_permissions() {
        let dir = tempfile::tempdir().unwrap();
        let real = dir.path().join("real.csv");
        write_atomic(&real, b"a").unwrap();
        #[cfg(unix)]
        {
            use std::os::unix::fs::PermissionsExt;
            std::fs::set_permissions(&real, std::fs::Permissions::from_mode(0o640)).unwrap();
            let link = dir.path().join("link.csv");
            std::os::unix::fs::symlink("real.csv", &link).unwrap();
            write_atomic(&link, b"b").unwrap();
            assert!(
                std::fs::symlink_metadata(&link)
                    .unwrap()
                    .file_type()
                    .is_symlink()
            );
            assert_eq!(std::fs::read(&real).unwrap(), b"b");
            let mode = std::fs::metadata(&real).unwrap().permissions().mode();
            assert_eq!(mode & 0o777, 0o640);
        }
    }

    #[test]
    fn a_directory_or_a_missing_folder_is_an_error() {
        let dir = tempfile::tempdir().unwrap();
        assert!(write_atomic(dir.path(), b"x").is_err());
        assert!(write_atomic(dir.path().join("no/such/dir/f.csv"), b"x").is_err());
    }

    #[test]
    fn temporary_keeps_the_extension() {
        let dir = tempfile::tempdir().unwrap();
        let af = AtomicFile::create(dir.path().join("fig.png")).unwrap();
        assert_eq!(af.temp_path().extension().unwrap(), "png");
        assert_eq!(af.temp_path().parent().unwrap(), dir.path());
        let t = af.temp_path().to_path_buf();
        drop(af);
        assert!(!t.exists());
    }

    /// A device node, a FIFO or a read-only file is refused and left as it was; nothing is
    /// created beside it.
    #[cfg(unix)]
    #[test]
    fn special_and_read_only_targets_are_refused() {
        use std::os::unix::fs::{FileTypeExt, PermissionsExt};
        let dir = tempfile::tempdir().unwrap();
        // A device node of our own (only root may make one): a regression replaces nothing
        // outside the test's folder.
        let dev = dir.path().join("null");
        let made = std::process::Command::new("mknod")
            .arg(&dev)
            .args(["c", "1", "3"])
            .status();
        if made.is_ok_and(|s| s.success()) {
            let e = write_atomic(&dev, b"model").unwrap_err();
            assert!(e.to_string().contains("character device"), "{e}");
            assert!(
                std::fs::metadata(&dev)
                    .unwrap()
                    .file_type()
                    .is_char_device()
            );
        }
        let fifo = dir.path().join("pipe.json");
        let made = std::process::Command::new("mkfifo").arg(&fifo).status();
        if made.map(|s| s.success()).unwrap_or(false) {
            let e = write_atomic(&fifo, b"model").unwrap_err();
            assert!(e.to_string().contains("FIFO"), "{e}");
            assert!(std::fs::metadata(&fifo).unwrap().file_type().is_fifo());
        }
        let ro = dir.path().join("ro.json");
        write_atomic(&ro, b"keep me").unwrap();
        std::fs::set_permissions(&ro, std::fs::Permissions::from_mode(0o444)).unwrap();
        let e = write_atomic(&ro, b"new").unwrap_err();
        assert_eq!(e.kind(), std::io::ErrorKind::PermissionDenied);
        assert!(e.to_string().contains("read-only"), "{e}");
        assert_eq!(std::fs::read(&ro).unwrap(), b"keep me");
        // Through a symbolic link too.
        let link = dir.path().join("link.json");
        std::os::unix::fs::symlink(&ro, &link).unwrap();
        assert!(write_atomic(&link, b"new").is_err());
        assert_eq!(std::fs::read(&ro).unwrap(), b"keep me");
        assert!(temps(dir.path()).is_empty(), "{:?}", temps(dir.path()));
    }

    /// A set whose last file fails leaves every previous file of the set unchanged.
    #[test]
    fn a_set_is_written_all_or_none() {
        let dir = tempfile::tempdir().unwrap();
        let (a, b) = (dir.path().join("a.csv"), dir.path().join("b.csv"));
        write_atomic(&a, b"old a").unwrap();
        write_atomic(&b, b"old b").unwrap();
        let mut set = AtomicSet::new();
        set.add_with(&a, |w| w.write_all(b"new a")).unwrap();
        let failed = set.add_with(&b, |w| {
            w.write_all(b"half")?;
            Err(std::io::Error::other("producer failed"))
        });
        assert!(failed.is_err());
        drop(set);
        assert_eq!(std::fs::read(&a).unwrap(), b"old a");
        assert_eq!(std::fs::read(&b).unwrap(), b"old b");
        assert!(temps(dir.path()).is_empty());
        let mut set = AtomicSet::new();
        set.add_with(&a, |w| w.write_all(b"new a")).unwrap();
        set.add_with(&b, |w| w.write_all(b"new b")).unwrap();
        assert_eq!(set.commit().unwrap(), vec![a.clone(), b.clone()]);
        assert_eq!(std::fs::read(&b).unwrap(), b"new b");
    }
}
