//! Temporary files to remove if the program is interrupted. Output is written to a
//! temporary file beside its target and renamed into place when complete; an ordinary
//! error drops the file (and so removes it), but Ctrl-C or SIGTERM ends the process
//! without running destructors. The command line therefore installs
//! [`remove_on_interrupt`], which deletes every file still listed here and exits.

use std::collections::HashSet;
use std::path::{Path, PathBuf};
use std::sync::Mutex;

static PENDING: Mutex<Option<HashSet<PathBuf>>> = Mutex::new(None);

/// Lists a temporary file to remove if the process is interrupted.
pub fn register(path: &Path) {
    let mut guard = PENDING.lock().unwrap_or_else(|e| e.into_inner());
    guard.get_or_insert_with(HashSet::new).insert(path.to_owned());
}

/// Takes a file off the list (it was renamed into place or removed).
pub fn forget(path: &Path) {
    let mut guard = PENDING.lock().unwrap_or_else(|e| e.into_inner());
    if let Some(set) = guard.as_mut() {
        set.remove(path);
    }
}

/// Removes the files in `set`; returns how many were removed.
fn remove_listed(set: &mut HashSet<PathBuf>) -> usize {
    set.drain().filter(|p| std::fs::remove_file(p).is_ok()).count()
}

/// Installs a handler for Ctrl-C (SIGINT), SIGTERM and SIGHUP (Windows: Ctrl-C and
/// Ctrl-Break) that removes the unfinished output files and exits with status 130.
/// An output renamed into place before the signal is complete and stays; one not yet
/// renamed is removed, so an older file of that name is left untouched.
pub fn remove_on_interrupt() -> Result<(), String> {
    ctrlc::set_handler(|| {
        // The lock stays held until the process exits, so that no temporary file can
        // be listed after this and then left behind.
        let mut hold = PENDING.lock().unwrap_or_else(|e| e.into_inner());
        let removed = hold.as_mut().map_or(0, remove_listed);
        if removed > 0 {
            eprintln!("\ninterrupted: removed the unfinished output");
        } else {
            eprintln!("\ninterrupted");
        }
        std::process::exit(130);
    })
    .map_err(|e| format!("cannot install the interrupt handler: {e}"))
}

#[cfg(test)]
mod tests {
    use super::*;

    fn listed(p: &Path) -> bool {
        PENDING.lock().unwrap().as_ref().is_some_and(|s| s.contains(p))
    }

    #[test]
    fn listed_files_are_removed_and_forgotten_ones_kept() {
        let dir = tempfile::tempdir().unwrap();
        let (a, b) = (dir.path().join("a.tmp"), dir.path().join("b.tmp"));
        std::fs::write(&a, b"a").unwrap();
        register(&a);
        register(&b);
        assert!(listed(&a) && listed(&b));
        forget(&b);
        forget(&a);
        assert!(!listed(&a) && !listed(&b));
        let mut set: HashSet<PathBuf> = [a.clone(), b.clone()].into();
        assert_eq!(remove_listed(&mut set), 1); // b never existed
        assert!(!a.exists() && set.is_empty());
    }
}
