//! Hostile inputs and outputs (issue 16): each test is one defect of the adversarial run, as a
//! user meets it through the example binaries, which `common::example_bin` builds first.

use std::io::{BufRead, BufReader, Read, Write};
use std::net::TcpStream;
use std::path::{Path, PathBuf};
use std::process::{Command, Output, Stdio};
use std::time::{Duration, Instant};

mod common;

use common::example_bin as bin;

fn run(name: &str, args: &[&str], cwd: &Path) -> Output {
    common::run_example(name, args, cwd)
}

/// A quick simulated scan.
const SMALL: &[&str] = &[
    "--builtin",
    "sphere",
    "--snapshots",
    "4",
    "--frames",
    "1",
    "--leaf",
    "0.004",
    "-q",
];

fn scan(extra: &[&str], cwd: &Path) -> Output {
    run("scan", &[SMALL, extra].concat(), cwd)
}

fn stderr(o: &Output) -> String {
    String::from_utf8_lossy(&o.stderr).into_owned()
}

/// Temporary files left in `dir`.
fn temporaries(dir: &Path) -> Vec<String> {
    std::fs::read_dir(dir)
        .unwrap()
        .map(|e| e.unwrap().file_name().to_string_lossy().into_owned())
        .filter(|n| n.starts_with('.') || n.contains("tmp") || n.contains("partial"))
        .collect()
}

use common::assert_refused;

// ---- 1. outputs are written to, not replaced, when they are not regular files ----------

#[test]
fn d01_out_through_a_symlink_to_a_device_writes_to_the_device() {
    let dir = tempfile::tempdir().unwrap();
    std::os::unix::fs::symlink("/dev/null", dir.path().join("fakenull")).unwrap();
    let o = scan(&["--out", "fakenull"], dir.path());
    assert!(o.status.success(), "{}", stderr(&o));
    let link = std::fs::symlink_metadata(dir.path().join("fakenull")).unwrap();
    assert!(link.file_type().is_symlink(), "the link was replaced");
    assert!(!std::fs::metadata("/dev/null").unwrap().is_file());
    assert!(temporaries(dir.path()).is_empty());
}

#[test]
fn d01_stats_through_a_symlink_to_stdout_prints_the_json() {
    let dir = tempfile::tempdir().unwrap();
    std::os::unix::fs::symlink("/proc/self/fd/1", dir.path().join("s.json")).unwrap();
    let o = scan(&["--out", "x.stl", "--stats", "s.json"], dir.path());
    assert!(o.status.success(), "{}", stderr(&o));
    let out = String::from_utf8_lossy(&o.stdout);
    assert!(out.contains("\"mesh_triangles\""), "stdout: {out}");
    assert!(
        std::fs::symlink_metadata(dir.path().join("s.json"))
            .unwrap()
            .file_type()
            .is_symlink()
    );
}

#[test]
fn d01_out_symlink_replaces_its_target_and_keeps_the_link() {
    let dir = tempfile::tempdir().unwrap();
    std::fs::write(dir.path().join("real.stl"), b"old").unwrap();
    std::os::unix::fs::symlink("real.stl", dir.path().join("link.stl")).unwrap();
    let o = scan(&["--out", "link.stl"], dir.path());
    assert!(o.status.success(), "{}", stderr(&o));
    assert!(
        std::fs::symlink_metadata(dir.path().join("link.stl"))
            .unwrap()
            .file_type()
            .is_symlink()
    );
    assert!(
        std::fs::metadata(dir.path().join("real.stl"))
            .unwrap()
            .len()
            > 84
    );
}

#[test]
fn d01_dash_writes_the_stl_to_stdout() {
    let dir = tempfile::tempdir().unwrap();
    let o = scan(&["--out", "-"], dir.path());
    assert!(o.status.success(), "{}", stderr(&o));
    assert!(o.stdout.len() > 84);
    let count = u32::from_le_bytes(o.stdout[80..84].try_into().unwrap()) as usize;
    assert_eq!(o.stdout.len(), 84 + 50 * count);
    assert!(!dir.path().join("-").exists());
}

// ---- 2. two flags naming one file -----------------------------------------------------

#[test]
fn d02_same_path_for_two_outputs_is_refused_naming_both_flags() {
    let dir = tempfile::tempdir().unwrap();
    std::fs::create_dir(dir.path().join("sub")).unwrap();
    std::os::unix::fs::symlink("x.stl", dir.path().join("l.stl")).unwrap();
    for (a, b) in [
        (["--out", "same.stl"], ["--stats", "same.stl"]),
        (["--out", "x.stl"], ["--stats", "./sub/../x.stl"]),
        (["--out", "x.stl"], ["--stats", "l.stl"]),
    ] {
        let o = scan(&[&a[..], &b[..]].concat(), dir.path());
        assert_refused(&o, &[a[0], b[0], "same file"]);
        assert!(!dir.path().join("same.stl").exists());
        assert!(!dir.path().join("x.stl").exists());
        assert!(temporaries(dir.path()).is_empty());
    }
}

/// A recorded scan to read, made with the scanner itself.
fn recorded(dir: &Path) -> PathBuf {
    let o = scan(&["--out", "r.stl", "--record-to", "rec"], dir);
    assert!(o.status.success(), "{}", stderr(&o));
    dir.join("rec")
}

#[test]
fn d02_inspect_out_and_views_on_one_file_is_refused() {
    let dir = tempfile::tempdir().unwrap();
    recorded(dir.path());
    let o = run(
        "inspect",
        &[
            "--input",
            "rec",
            "--snapshot",
            "0",
            "--out",
            "a.png",
            "--views",
            "a.png",
        ],
        dir.path(),
    );
    assert_refused(&o, &["--out", "--views"]);
    assert!(!dir.path().join("a.png").exists());
}

// ---- 3. output paths checked before the work -------------------------------------------

#[test]
fn d03_bad_output_directories_are_refused_before_any_work() {
    let dir = tempfile::tempdir().unwrap();
    std::fs::write(dir.path().join("file"), b"x").unwrap();
    for (flag, path, needle) in [
        ("--out", "missing/x.stl", "does not exist"),
        ("--out", "newdir/", "directory"),
        ("--out", "file/x.stl", "not a directory"),
        ("--stats", "missing/s.json", "does not exist"),
        ("--preview", "file/p.png", "not a directory"),
    ] {
        // The default scan takes seconds; a refusal before the work takes milliseconds.
        let t = Instant::now();
        let o = run(
            "scan",
            &["--out", "ok.stl", flag, path, "-q"][if flag == "--out" { 2 } else { 0 }..],
            dir.path(),
        );
        assert_refused(&o, &[flag, needle]);
        let e = stderr(&o);
        assert_eq!(e.matches(path).count(), 1, "path printed once: {e}");
        assert!(
            t.elapsed() < Duration::from_secs(20),
            "{flag} {path} refused only after the work"
        );
        assert!(!dir.path().join("ok.stl").exists());
    }
}

#[test]
fn d03_lod_deeper_than_the_octree_is_refused_up_front() {
    let dir = tempfile::tempdir().unwrap();
    let o = scan(&["--out", "x.stl", "--lod", "30"], dir.path());
    assert_refused(&o, &["--lod"]);
}

// ---- 4. all or nothing ------------------------------------------------------------------

#[test]
fn d04_a_failing_side_output_replaces_nothing_and_names_the_users_path() {
    let dir = tempfile::tempdir().unwrap();
    std::fs::write(dir.path().join("out.stl"), b"old").unwrap();
    let o = scan(
        &[
            "--out",
            "out.stl",
            "--stats",
            "/dev/full",
            "--preview",
            "p.png",
        ],
        dir.path(),
    );
    assert_refused(&o, &["--stats /dev/full"]);
    let e = stderr(&o);
    assert!(!e.contains("tmp") && !e.contains("partial"), "{e}");
    assert_eq!(std::fs::read(dir.path().join("out.stl")).unwrap(), b"old");
    assert!(!dir.path().join("p.png").exists());
    assert!(
        temporaries(dir.path()).is_empty(),
        "{:?}",
        temporaries(dir.path())
    );
}

// ---- 5. signals remove temporary files ---------------------------------------------------

#[test]
fn d05_sigterm_while_a_temporary_file_exists_removes_it_and_keeps_the_old_output() {
    let dir = tempfile::tempdir().unwrap();
    std::fs::write(dir.path().join("k.stl"), b"old").unwrap();
    let bin = bin("scan");
    let mut child = Command::new(bin)
        .args(["--builtin", "sphere", "--leaf", "0.002", "--ascii", "-q"])
        .args(["--out", "k.stl"])
        .current_dir(dir.path())
        .stdout(Stdio::null())
        .stderr(Stdio::null())
        .spawn()
        .unwrap();
    // Signal as soon as a temporary file appears (bounded wait).
    let t = Instant::now();
    let mut signalled = false;
    while t.elapsed() < Duration::from_secs(120) {
        if !temporaries(dir.path()).is_empty() {
            Command::new("kill")
                .args(["-TERM", &child.id().to_string()])
                .status()
                .unwrap();
            signalled = true;
            break;
        }
        if child.try_wait().unwrap().is_some() {
            break;
        }
        std::thread::sleep(Duration::from_millis(1));
    }
    let status = child.wait().unwrap();
    assert!(signalled, "no temporary file was seen");
    assert!(!status.success());
    assert!(
        temporaries(dir.path()).is_empty(),
        "left behind: {:?}",
        temporaries(dir.path())
    );
    assert_eq!(std::fs::read(dir.path().join("k.stl")).unwrap(), b"old");
}

// ---- 6. calibrate --write ------------------------------------------------------------------

#[test]
fn d06_calibrate_write_refuses_a_read_only_manifest_before_the_work() {
    use std::os::unix::fs::PermissionsExt;
    let dir = tempfile::tempdir().unwrap();
    let rec = recorded(dir.path());
    let manifest = rec.join("scan.toml");
    std::fs::set_permissions(&manifest, std::fs::Permissions::from_mode(0o444)).unwrap();
    let before = std::fs::read(&manifest).unwrap();
    let o = run("calibrate", &["--input", "rec", "--write"], dir.path());
    assert_refused(&o, &["read-only"]);
    assert_eq!(std::fs::read(&manifest).unwrap(), before);
    let mode = std::fs::metadata(&manifest).unwrap().permissions().mode() & 0o777;
    assert_eq!(mode, 0o444);
}

#[test]
fn d06_calibrate_write_updates_a_symlinks_target_keeping_comments_keys_and_mode() {
    use std::os::unix::fs::PermissionsExt;
    let dir = tempfile::tempdir().unwrap();
    let o = run(
        "scan",
        &[
            "--builtin",
            "figurine",
            "--snapshots",
            "8",
            "--frames",
            "1",
            "--leaf",
            "0.004",
            "-q",
            "--out",
            "r.stl",
            "--record-to",
            "rec",
        ],
        dir.path(),
    );
    assert!(o.status.success(), "{}", stderr(&o));
    let rec = dir.path().join("rec");
    // The manifest lives elsewhere, with a comment, an unknown key and mode 0640.
    std::fs::create_dir(dir.path().join("store")).unwrap();
    let text = std::fs::read_to_string(rec.join("scan.toml")).unwrap();
    let text = format!("# bunny, 3rd try\n{text}\n[notes]\nlamp = \"off\" # keep me\n");
    let real = dir.path().join("store/scan.toml");
    std::fs::write(&real, &text).unwrap();
    std::fs::set_permissions(&real, std::fs::Permissions::from_mode(0o640)).unwrap();
    std::fs::remove_file(rec.join("scan.toml")).unwrap();
    std::os::unix::fs::symlink("../store/scan.toml", rec.join("scan.toml")).unwrap();
    let o = run("calibrate", &["--input", "rec", "--write"], dir.path());
    assert!(o.status.success(), "{}", stderr(&o));
    assert!(
        std::fs::symlink_metadata(rec.join("scan.toml"))
            .unwrap()
            .file_type()
            .is_symlink(),
        "the link was replaced"
    );
    let after = std::fs::read_to_string(&real).unwrap();
    assert!(after.contains("# bunny, 3rd try"), "{after}");
    assert!(after.contains("lamp = \"off\" # keep me"), "{after}");
    let changed = text
        .lines()
        .zip(after.lines())
        .filter(|(a, b)| a != b)
        .count();
    assert!(changed <= 2, "only the rig lines change:\n{after}");
    let mode = std::fs::metadata(&real).unwrap().permissions().mode() & 0o777;
    assert_eq!(mode, 0o640);
    assert!(temporaries(&rec).is_empty() && temporaries(&dir.path().join("store")).is_empty());
}

// ---- 7a. --record-to over a recorded scan ----------------------------------------------

#[test]
fn d07a_record_to_a_directory_holding_a_scan_is_refused_unless_forced() {
    let dir = tempfile::tempdir().unwrap();
    let rec = recorded(dir.path());
    let manifest_before = std::fs::read(rec.join("scan.toml")).unwrap();
    let o = run(
        "scan",
        &[
            "--builtin",
            "box",
            "--snapshots",
            "2",
            "--frames",
            "1",
            "--leaf",
            "0.004",
            "-q",
            "--out",
            "c.stl",
            "--record-to",
            "rec",
        ],
        dir.path(),
    );
    assert_refused(&o, &["--record-to", "--force"]);
    assert_eq!(
        std::fs::read(rec.join("scan.toml")).unwrap(),
        manifest_before
    );
    assert!(!dir.path().join("c.stl").exists());

    let o = run(
        "scan",
        &[
            "--builtin",
            "box",
            "--snapshots",
            "2",
            "--frames",
            "1",
            "--leaf",
            "0.004",
            "-q",
            "--out",
            "c.stl",
            "--record-to",
            "rec",
            "--force",
        ],
        dir.path(),
    );
    assert!(o.status.success(), "{}", stderr(&o));
    let frames = std::fs::read_dir(rec.join("frames")).unwrap().count();
    assert_eq!(frames, 2, "the old frames are gone, the new two remain");

    std::fs::write(dir.path().join("other.txt"), b"x").unwrap();
    let o = scan(&["--out", "y.stl", "--record-to", "."], dir.path());
    assert_refused(&o, &["--record-to", "not empty"]);
}

/// Runs an example with a bound on its time: a hang is a failure, not a stuck test. Its
/// output goes to files, not pipes, so a child that writes more than a pipe holds cannot
/// block unread while it is waited for.
fn run_bounded(name: &str, args: &[&str], cwd: &Path, limit: Duration) -> Output {
    let logs = tempfile::tempdir().unwrap();
    let (out, err) = (logs.path().join("stdout"), logs.path().join("stderr"));
    let mut child = Command::new(bin(name))
        .args(args)
        .current_dir(cwd)
        .stdout(std::fs::File::create(&out).unwrap())
        .stderr(std::fs::File::create(&err).unwrap())
        .spawn()
        .unwrap();
    let status = wait_bounded(&mut child, limit, &format!("{name} {args:?}"));
    Output {
        status,
        stdout: std::fs::read(&out).unwrap(),
        stderr: std::fs::read(&err).unwrap(),
    }
}

/// Rewrites the recorded scan's manifest with `edit`.
fn edit_manifest(rec: &Path, edit: impl FnOnce(String) -> String) {
    let p = rec.join("scan.toml");
    let text = std::fs::read_to_string(&p).unwrap();
    std::fs::write(&p, edit(text)).unwrap();
}

// ---- 7–10. resource limits --------------------------------------------------------------

#[test]
fn d07_a_manifest_listing_one_frame_thousands_of_times_is_refused_up_front() {
    let dir = tempfile::tempdir().unwrap();
    let rec = recorded(dir.path());
    let many = vec!["\"frames/s000_f00.png\""; 2000].join(", ");
    edit_manifest(&rec, |t| {
        t.lines()
            .map(|l| {
                if l.trim_start().starts_with("frames = ") {
                    format!("frames = [{many}]")
                } else {
                    l.to_owned()
                }
            })
            .collect::<Vec<_>>()
            .join("\n")
    });
    let o = run_bounded(
        "scan",
        &[
            "--input",
            "rec",
            "--out",
            "x.stl",
            "-q",
            "--max-memory",
            "1G",
        ],
        dir.path(),
        Duration::from_secs(60),
    );
    assert_refused(&o, &["needs about", "--max-memory"]);
}

/// A PNG header claiming `w`×`h` 16-bit grey pixels, and no pixels.
fn png_header_only(w: u32, h: u32) -> Vec<u8> {
    let mut buf = Vec::new();
    {
        let mut enc = png::Encoder::new(&mut buf, w, h);
        enc.set_color(png::ColorType::Grayscale);
        enc.set_depth(png::BitDepth::Sixteen);
        let mut writer = enc.write_header().unwrap();
        // A few bytes of pixels: the decoder stops at the first IDAT to report the header.
        writer
            .write_chunk(png::chunk::IDAT, &[0x78, 0x9c, 0x03, 0, 0, 0, 0, 1])
            .unwrap();
        std::mem::forget(writer);
    }
    buf
}

#[test]
fn d08_a_png_header_claiming_a_huge_frame_is_refused_before_decoding() {
    let dir = tempfile::tempdir().unwrap();
    let rec = recorded(dir.path());
    std::fs::write(
        rec.join("frames/s000_f00.png"),
        png_header_only(100_000, 100_000),
    )
    .unwrap();
    let o = run_bounded(
        "scan",
        &["--input", "rec", "--out", "x.stl", "-q"],
        dir.path(),
        Duration::from_secs(60),
    );
    assert_refused(&o, &["100000x100000", "s000_f00.png"]);
}

#[test]
fn d09_flags_that_would_need_terabytes_are_refused_with_the_estimate() {
    let dir = tempfile::tempdir().unwrap();
    for (args, needle) in [
        (&["--snapshots", "3600", "--frames", "1000"][..], "frames"),
        (&["--leaf", "1e-5"][..], "--leaf"),
    ] {
        let o = run_bounded(
            "scan",
            &[args, &["--out", "x.stl", "-q"]].concat(),
            dir.path(),
            Duration::from_secs(60),
        );
        assert_refused(&o, &["needs about", needle, "--max-memory"]);
    }
}

#[test]
fn d10_a_model_that_is_not_a_regular_file_is_refused() {
    let dir = tempfile::tempdir().unwrap();
    std::os::unix::fs::symlink("/dev/zero", dir.path().join("zero.stl")).unwrap();
    let o = run_bounded(
        "scan",
        &["--model", "zero.stl", "--out", "x.stl", "-q"],
        dir.path(),
        Duration::from_secs(60),
    );
    assert_refused(&o, &["--model", "not a regular file"]);
}

// ---- 11. paths inside a recorded scan --------------------------------------------------------

#[test]
fn d11_frame_paths_outside_the_scan_or_not_regular_files_are_refused() {
    let dir = tempfile::tempdir().unwrap();
    let rec = recorded(dir.path());
    let original = std::fs::read_to_string(rec.join("scan.toml")).unwrap();
    std::fs::copy(
        rec.join("frames/s000_f00.png"),
        dir.path().join("outside.png"),
    )
    .unwrap();
    let input = ["--input", "rec", "--out", "x.stl", "-q"];
    // Lexically outside: refused alike whether or not the file exists.
    for bad in ["../outside.png", "/etc/passwd", "/no/such/file.png"] {
        std::fs::write(
            rec.join("scan.toml"),
            original.replace("frames/s000_f00.png", bad),
        )
        .unwrap();
        let o = run_bounded("scan", &input, dir.path(), Duration::from_secs(60));
        assert_refused(&o, &["inside the scan directory"]);
    }
    std::fs::write(rec.join("scan.toml"), &original).unwrap();
    // Outside through a symlink.
    std::fs::remove_file(rec.join("frames/s000_f00.png")).unwrap();
    std::os::unix::fs::symlink("../../outside.png", rec.join("frames/s000_f00.png")).unwrap();
    let o = run_bounded("scan", &input, dir.path(), Duration::from_secs(60));
    assert_refused(&o, &["leaves the scan directory"]);
    // A FIFO does not hang the run.
    std::fs::remove_file(rec.join("frames/s000_f00.png")).unwrap();
    let made = Command::new("mkfifo")
        .arg(rec.join("frames/s000_f00.png"))
        .status()
        .unwrap();
    assert!(made.success());
    let o = run_bounded("scan", &input, dir.path(), Duration::from_secs(60));
    assert_refused(&o, &["not a regular file"]);
}

// ---- 12–15. the turntable server -------------------------------------------------------------

/// Starts the server on a free loopback port; returns the child and the address it printed.
fn server(args: &[&str], envs: &[(&str, &str)]) -> (std::process::Child, String) {
    let mut cmd = Command::new(bin("turntable_server"));
    cmd.args(["--listen", "127.0.0.1:0"])
        .args(args)
        .env_remove("VOXOCT_TURNTABLE_TOKEN")
        .env_remove("VOXOCT_TT_TOKEN")
        .stdout(Stdio::null())
        .stderr(Stdio::piped());
    for (k, v) in envs {
        cmd.env(k, v);
    }
    let mut child = cmd.spawn().unwrap();
    let mut err = BufReader::new(child.stderr.take().unwrap());
    let t = Instant::now();
    let mut line = String::new();
    while t.elapsed() < Duration::from_secs(30) {
        line.clear();
        if err.read_line(&mut line).unwrap_or(0) == 0 {
            break;
        }
        if let Some(rest) = line.split("listening on ").nth(1) {
            let addr = rest.split_whitespace().next().unwrap().to_owned();
            // Keep draining stderr so the server never blocks on it.
            std::thread::spawn(move || drain(err));
            return (child, addr);
        }
    }
    let _ = child.kill();
    let _ = child.wait();
    panic!("the server did not start: {line}");
}

fn connect(addr: &str) -> (TcpStream, BufReader<TcpStream>) {
    let s = TcpStream::connect(addr).unwrap();
    s.set_read_timeout(Some(Duration::from_secs(10))).unwrap();
    let r = BufReader::new(s.try_clone().unwrap());
    (s, r)
}

/// Waits for `child` (`what`, for the message), killing it and failing after `limit`.
fn wait_bounded(
    child: &mut std::process::Child,
    limit: Duration,
    what: &str,
) -> std::process::ExitStatus {
    let t = Instant::now();
    loop {
        if let Some(st) = child.try_wait().unwrap() {
            return st;
        }
        if t.elapsed() > limit {
            let _ = child.kill();
            let _ = child.wait();
            panic!("{what} still running after {limit:?}");
        }
        std::thread::sleep(Duration::from_millis(20));
    }
}

#[test]
fn d12_a_nonsensical_sim_speed_is_refused_at_start() {
    let dir = tempfile::tempdir().unwrap();
    let o = run_bounded(
        "turntable_server",
        &["--listen", "127.0.0.1:0", "--sim-speed", "1e-20"],
        dir.path(),
        Duration::from_secs(30),
    );
    assert_refused(&o, &["--sim-speed"]);
}

#[test]
fn d14_sigint_during_a_turn_finishes_it_replies_and_exits_0() {
    let (mut child, addr) = server(&["--sim-speed", "90"], &[]);
    let (mut s, mut r) = connect(&addr);
    send(&mut s, "VOXOCT-TT/1");
    assert!(read_line(&mut r).starts_with("OK "));
    send(&mut s, "ROTATE 90"); // one second at 90°/s
    std::thread::sleep(Duration::from_millis(300));
    Command::new("kill")
        .args(["-INT", &child.id().to_string()])
        .status()
        .unwrap();
    let reply = read_line(&mut r);
    assert!(
        reply.starts_with("OK 90"),
        "the turn should finish: {reply:?}"
    );
    let bye = read_line(&mut r);
    assert!(bye.contains("shutting down"), "{bye:?}");
    let status = wait_bounded(&mut child, Duration::from_secs(10), "the server");
    assert!(status.success(), "{status:?}");
}

#[test]
fn d15_the_server_reads_the_token_from_voxoct_turntable_token() {
    let (mut child, addr) = server(&[], &[("VOXOCT_TURNTABLE_TOKEN", "s3cret")]);
    let (mut s, mut r) = connect(&addr);
    send(&mut s, "VOXOCT-TT/1");
    assert!(read_line(&mut r).starts_with("ERR UNAUTHORISED"));
    let (mut s, mut r) = connect(&addr);
    send(&mut s, "VOXOCT-TT/1 s3cret");
    assert!(read_line(&mut r).starts_with("OK "));
    send(&mut s, "QUIT");
    let _ = read_line(&mut r);
    Command::new("kill")
        .args(["-TERM", &child.id().to_string()])
        .status()
        .unwrap();
    assert!(wait_bounded(&mut child, Duration::from_secs(10), "the server").success());

    let dir = tempfile::tempdir().unwrap();
    let bin = bin("turntable_server");
    let o = Command::new(bin)
        .args(["--listen", "127.0.0.1:0"])
        .env_remove("VOXOCT_TURNTABLE_TOKEN")
        .env("VOXOCT_TT_TOKEN", "s3cret")
        .current_dir(dir.path())
        .output()
        .unwrap();
    assert_refused(&o, &["VOXOCT_TURNTABLE_TOKEN"]);
}

// ---- 16–17. flags and messages -----------------------------------------------------------------

#[test]
fn d16_unbounded_values_and_flags_of_another_source_are_refused() {
    let dir = tempfile::tempdir().unwrap();
    recorded(dir.path());
    for (args, needles) in [
        (&["--smooth", "4294967295"][..], &["--smooth"][..]),
        (&["--min-hits", "4294967295"][..], &["--min-hits"][..]),
        (
            &["--min-component", "18446744073709551615"][..],
            &["--min-component"][..],
        ),
        (
            &["--input", "rec", "--degrees-per-snapshot", "45"][..],
            &["--degrees-per-snapshot", "does not apply"][..],
        ),
        (
            &["--input", "rec", "--snapshots", "3"][..],
            &["--snapshots", "does not apply"][..],
        ),
        (
            &["--input", "rec", "--seed", "3"][..],
            &["--seed", "does not apply"][..],
        ),
    ] {
        let o = run_bounded(
            "scan",
            &[args, &["--out", "x.stl", "-q"]].concat(),
            dir.path(),
            Duration::from_secs(60),
        );
        assert_refused(&o, needles);
    }
}

#[test]
fn d17_messages_say_what_is_wrong() {
    let dir = tempfile::tempdir().unwrap();
    let rec = recorded(dir.path());
    std::fs::write(dir.path().join("model.stl"), b"solid x\nendsolid x\n").unwrap();
    let original = std::fs::read_to_string(rec.join("scan.toml")).unwrap();
    let cases: Vec<(Vec<&str>, Vec<&str>)> = vec![
        (vec!["--leaf", "0.5"], vec!["--leaf is in metres"]),
        (vec!["--input", "model.stl"], vec!["is a file", "--model"]),
        (vec!["--lod", "10"], vec!["--lod"]),
    ];
    for (args, needles) in cases {
        let args: Vec<&str> = if args[0] == "--input" || args[0] == "--leaf" {
            args
        } else {
            [&args[..], SMALL].concat()
        };
        let o = run_bounded(
            "scan",
            &[&args[..], &["--out", "x.stl"]].concat(),
            dir.path(),
            Duration::from_secs(120),
        );
        assert_refused(&o, &needles);
        assert!(
            !stderr(&o).contains("is the object inside the clip box"),
            "{}",
            stderr(&o)
        );
    }
    // All-zero frames: the message says there was no valid pixel.
    let zero_dir = dir.path().join("zero");
    std::fs::create_dir_all(zero_dir.join("frames")).unwrap();
    std::fs::write(zero_dir.join("scan.toml"), &original).unwrap();
    for k in 0..4 {
        let mut buf = Vec::new();
        let mut enc = png::Encoder::new(&mut buf, 640, 480);
        enc.set_color(png::ColorType::Grayscale);
        enc.set_depth(png::BitDepth::Sixteen);
        let mut w = enc.write_header().unwrap();
        w.write_image_data(&vec![0u8; 640 * 480 * 2]).unwrap();
        w.finish().unwrap();
        std::fs::write(zero_dir.join(format!("frames/s{k:03}_f00.png")), buf).unwrap();
    }
    let o = run(
        "scan",
        &["--input", "zero", "--out", "x.stl", "-q"],
        dir.path(),
    );
    assert_refused(&o, &["no frame had a valid depth pixel"]);
    // Out of range for f32, not "non-finite"; a subnormal unit is out of range too.
    for (key, to) in [("depth_unit_m", "1e-45"), ("angle_deg", "1e300")] {
        let edited = set_first(&original, key, to);
        std::fs::write(rec.join("scan.toml"), edited).unwrap();
        let o = run(
            "scan",
            &["--input", "rec", "--out", "x.stl", "-q"],
            dir.path(),
        );
        assert_refused(&o, &[key, "out of range"]);
    }
    // Control bytes in a frame name are escaped; a huge message is cut.
    std::fs::write(
        rec.join("scan.toml"),
        original.replacen("frames/s000_f00.png", "frames/\u{1b}[31mred\u{7}.png", 1),
    )
    .unwrap();
    let o = run(
        "scan",
        &["--input", "rec", "--out", "x.stl", "-q"],
        dir.path(),
    );
    assert!(
        !o.stderr.contains(&0x1b) && !o.stderr.contains(&0x07),
        "{}",
        stderr(&o)
    );
    assert!(stderr(&o).contains("\\u{1b}"), "{}", stderr(&o));
    let deep = format!("x = {}1{}\n", "[".repeat(20_000), "]".repeat(20_000));
    std::fs::write(rec.join("scan.toml"), format!("{deep}{original}")).unwrap();
    let o = run(
        "scan",
        &["--input", "rec", "--out", "x.stl", "-q"],
        dir.path(),
    );
    assert!(!o.status.success());
    assert!(o.stderr.len() < 5000, "{} bytes", o.stderr.len());
    // inspect --scale-mm takes a number, and a negative one is refused as such.
    let o = run(
        "inspect",
        &[
            "--input",
            "rec",
            "--snapshot",
            "0",
            "--versus",
            "basic",
            "--scale-mm",
            "-5",
            "--out",
            "d.png",
        ],
        dir.path(),
    );
    assert_refused(&o, &["--scale-mm must be a positive"]);
}

fn read_line(r: &mut BufReader<TcpStream>) -> String {
    let mut s = String::new();
    let _ = r.read_line(&mut s);
    s
}

fn drain(mut s: impl Read) -> Vec<u8> {
    let mut v = Vec::new();
    let _ = s.read_to_end(&mut v);
    v
}

fn send(s: &mut TcpStream, line: &str) {
    let _ = s.write_all(format!("{line}\n").as_bytes());
}

/// `text` with the first `key = …` line's value replaced by `value`.
fn set_first(text: &str, key: &str, value: &str) -> String {
    let mut done = false;
    text.lines()
        .map(|l| {
            if !done && l.trim_start().starts_with(&format!("{key} =")) {
                done = true;
                format!("{key} = {value}")
            } else {
                l.to_owned()
            }
        })
        .collect::<Vec<_>>()
        .join("\n")
}
