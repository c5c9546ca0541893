//! Tests of the confinement rule on real files, links, FIFOs and devices.

use super::*;

fn setup() -> (tempfile::TempDir, Confinement) {
    let dir = tempfile::tempdir().unwrap();
    std::fs::create_dir(dir.path().join("scn")).unwrap();
    std::fs::write(dir.path().join("scn/inside.bin"), b"inside").unwrap();
    std::fs::write(dir.path().join("outside.bin"), b"SECRET-BYTES").unwrap();
    let c = Confinement::new(&dir.path().join("scn"), &[]).unwrap();
    (dir, c)
}

#[test]
fn a_file_inside_is_read() {
    let (dir, c) = setup();
    let bytes = c.read(&dir.path().join("scn/inside.bin"), 100).unwrap();
    assert_eq!(bytes, b"inside");
}

#[test]
fn dot_dot_absolute_and_links_outside_are_refused_without_contents() {
    let (dir, c) = setup();
    let scn = dir.path().join("scn");
    std::os::unix::fs::symlink(dir.path().join("outside.bin"), scn.join("link.bin")).unwrap();
    for p in [
        scn.join("../outside.bin"),
        dir.path().join("outside.bin"),
        scn.join("link.bin"),
        PathBuf::from("/etc/passwd"),
    ] {
        let err = c.read(&p, 1 << 20).unwrap_err();
        assert!(err.contains("outside the folders"), "{err}");
        assert!(!err.contains("SECRET") && !err.contains("root:"), "{err}");
    }
}

#[test]
fn an_allowed_folder_admits_its_files() {
    let (dir, _) = setup();
    let c = Confinement::new(&dir.path().join("scn"), &[dir.path().to_path_buf()]).unwrap();
    assert_eq!(
        c.read(&dir.path().join("outside.bin"), 100).unwrap(),
        b"SECRET-BYTES"
    );
    assert!(
        Confinement::new(&dir.path().join("scn"), &[dir.path().join("absent")])
            .unwrap_err()
            .contains("absent")
    );
}

#[test]
fn system_files_devices_fifos_and_folders_are_refused_quickly() {
    let dir = tempfile::tempdir().unwrap();
    let fifo = dir.path().join("pipe.bin");
    let status = std::process::Command::new("mkfifo")
        .arg(&fifo)
        .status()
        .unwrap();
    assert!(status.success());
    let c = Confinement::new(dir.path(), &[PathBuf::from("/")]).unwrap();
    let start = std::time::Instant::now();
    let err = c.read(&fifo, 100).unwrap_err();
    assert!(err.contains("FIFO"), "{err}");
    for p in ["/dev/zero", "/proc/self/environ", "/sys/kernel/notes"] {
        let err = c.read(Path::new(p), 100).unwrap_err();
        assert!(err.contains("system file"), "{p}: {err}");
    }
    let err = c.read(dir.path(), 100).unwrap_err();
    assert!(err.contains("folder, not a regular file"), "{err}");
    assert!(start.elapsed().as_secs() < 5);
}

/// A scenario's folder under /dev/shm (tmpfs, a usual scratch place) is a data folder like any
/// other; only the devices under /dev are refused.
#[test]
fn files_under_dev_shm_are_data() {
    let shm = Path::new("/dev/shm");
    if !shm.is_dir() {
        eprintln!(
            "files_under_dev_shm_are_data: this machine has no /dev/shm; the rule is checked on the path alone"
        );
        assert!(!is_system(Path::new("/dev/shm/x/mesh.stl")));
        return;
    }
    let dir = tempfile::tempdir_in(shm).unwrap();
    std::fs::write(dir.path().join("mesh.stl"), b"solid").unwrap();
    let c = Confinement::new(dir.path(), &[]).unwrap();
    assert_eq!(c.read(&dir.path().join("mesh.stl"), 100).unwrap(), b"solid");
    assert!(is_system(Path::new("/dev/zero")));
    assert!(is_system(Path::new("/dev/shmx")));
}

#[test]
fn the_size_limit_is_checked_before_reading() {
    let (dir, c) = setup();
    let err = c.read(&dir.path().join("scn/inside.bin"), 3).unwrap_err();
    assert!(err.contains("more than the limit of 3 bytes"), "{err}");
}

#[test]
fn long_names_and_control_characters_are_cut() {
    let s = shorten(&format!("a\nb{}", "x".repeat(500)));
    assert!(s.starts_with("a?b") && s.ends_with('…'));
    assert_eq!(s.chars().count(), MAX_SHOWN_CHARS + 1);
}
