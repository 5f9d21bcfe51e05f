//! Bad input to `acch run` gives a clear error naming the input, and never
//! a panic: missing, corrupt and truncated images in a folder source,
//! corrupt, truncated and wrong-version databases, malformed TOML, NaN or
//! negative parameters. Frames of another size mid-stream are skipped and
//! the run goes on.

mod common;

use common::free_port;
use std::path::{Path, PathBuf};
use std::process::{Command, Output};
use std::sync::OnceLock;
use std::time::Duration;

/// Runs `acch ARGS` with a loopback zenoh port and a time limit.
fn acch(dir: &Path, args: &[&str]) -> Output {
    let cfg = dir.join("zenoh.toml");
    if !cfg.exists() {
        std::fs::write(
            &cfg,
            format!("[zenoh]\nlisten = [\"tcp/127.0.0.1:{}\"]\n", free_port()),
        )
        .unwrap();
    }
    let child = Command::new(env!("CARGO_BIN_EXE_acch"))
        .args(args)
        .stdout(std::process::Stdio::piped())
        .stderr(std::process::Stdio::piped())
        .spawn()
        .unwrap();
    let pid = child.id();
    // A watchdog: a hang is a failure too.
    let (tx, rx) = std::sync::mpsc::channel::<()>();
    std::thread::spawn(move || {
        if rx.recv_timeout(Duration::from_secs(240)).is_err() {
            // SAFETY: kill(2) on our own child.
            unsafe { libc::kill(pid as i32, libc::SIGKILL) };
        }
    });
    let out = child.wait_with_output().unwrap();
    let _ = tx.send(());
    out
}

/// The run failed cleanly: not a panic (exit 101, "panicked"), and stderr
/// names `what`.
fn fails_naming(out: &Output, what: &str) -> String {
    let err = String::from_utf8_lossy(&out.stderr).into_owned();
    eprintln!("{err}");
    assert!(!out.status.success(), "accepted bad input ({what})");
    assert_ne!(out.status.code(), Some(101), "panicked on {what}: {err}");
    assert!(
        out.status.code().is_some(),
        "killed by a signal on {what}: {err}"
    );
    assert!(!err.contains("panicked"), "a panic on {what}: {err}");
    assert!(err.contains(what), "the error does not name {what}: {err}");
    err
}

/// A bad frame either stops the run with an error naming it or is skipped
/// with a warning naming it; never a panic.
fn names_cleanly(out: &Output, what: &str) {
    let err = String::from_utf8_lossy(&out.stderr).into_owned();
    eprintln!("{err}");
    assert_ne!(out.status.code(), Some(101), "panicked on {what}: {err}");
    assert!(
        out.status.code().is_some(),
        "killed by a signal on {what}: {err}"
    );
    assert!(!err.contains("panicked"), "a panic on {what}: {err}");
    assert!(err.contains(what), "{what} is not named: {err}");
}

fn run_with_config(text: &str) -> Output {
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("pipeline.toml");
    std::fs::write(&path, text).unwrap();
    acch(dir.path(), &["run", "--config", path.to_str().unwrap()])
}

#[test]
fn malformed_toml_names_the_file_and_line() {
    let out = run_with_config("[camera]\nframes = 30\nfps = [1, \n");
    let err = fails_naming(&out, "pipeline.toml");
    assert!(err.contains("line 3"), "{err}");
}

#[test]
fn nan_negative_and_out_of_range_parameters_name_the_key() {
    for (text, key) in [
        ("[camera]\nfps = nan", "camera.fps = NaN"),
        ("[camera]\nfps = -30.0", "camera.fps = -30"),
        ("[camera]\ndistance_m = -5.0", "camera.distance_m = -5"),
        ("[camera]\ndistance_m = nan", "camera.distance_m = NaN"),
        ("[object]\nradius_m = 0.0", "object.radius_m = 0"),
        ("[ros2]\nnamespace = \"robot1\"", "ros2.namespace = robot1"),
        // A closed choice: refused as the file is read, by TOML's error,
        // which points at the line; ours names the key.
        (
            "[observers]\nrecord_format = \"rosbag\"",
            "(key `observers.record_format`)",
        ),
        ("[camera]\nframes = -1", "(key `camera.frames`)"),
        ("[camera]\nwidth = 0", "camera.width = 0"),
        ("[camera]\nheight = 99999", "camera.height = 99999"),
        ("[run]\nframe_history = 0", "run.frame_history = 0"),
        ("[run]\ntransport = \"carrier-pigeon\"", "carrier-pigeon"),
        ("[camera]\nsource = \"webcam\"", "camera.source = webcam"),
        ("[synthetic]\nbackground = \"mars\"", "mars"),
        (
            "[estimate]\nsmoothing = \"gaussian\"",
            "(key `estimate.smoothing`)",
        ),
        ("[run]\nstage_cpus = \"all\"", "(key `run.stage_cpus`)"),
        // An unknown key in a section, and a key of the flat layout.
        ("[camera]\nexposure = 2.0", "(key `camera.exposure`)"),
        ("fps = 30.0", "(key `fps`)"),
        ("[zenoh]\nlisten = \"tcp/127.0.0.1:7447\"", "listen"),
        (
            "[objects]\nlist = [\"fruitbox\", \"can\"]\nin_view = 3",
            "objects.in_view = 3",
        ),
        (
            "[objects]\nlist = [\"fruitbox\", \"can\"]\n[observers]\nrerun = \"spawn\"",
            "observers.rerun = spawn",
        ),
        (
            "[objects]\nlist = [\"fruitbox\", \"\"]",
            "objects.list = \"\"",
        ),
    ] {
        let out = run_with_config(text);
        fails_naming(&out, key);
    }
}

#[test]
fn nan_and_negative_command_line_values_name_the_option() {
    let dir = tempfile::tempdir().unwrap();
    for (args, what) in [
        (&["run", "--fps", "NaN"][..], "camera.fps = NaN"),
        (&["run", "--fps=-2"][..], "camera.fps = -2"),
        (&["run", "--frames=-3"][..], "--frames"),
        (&["run", "--resolution", "0x480"][..], "0x480"),
        (
            &["run", "--light-directions", "0"][..],
            "estimate.light_directions = 0",
        ),
        (
            &["eval", "--protocol", "robust", "--light-directions", "0"][..],
            "--light-directions",
        ),
        (
            &["run", "--stall-timeout", "nan", "--frames", "1"][..],
            "stall-timeout",
        ),
        (
            &["run", "--smoothing", "gaussian"][..],
            "unknown smoothing 'gaussian'",
        ),
        (
            &["run", "--transport", "udp"][..],
            "'--transport <TRANSPORT>'",
        ),
        (
            &["run", "--record-format", "bag"][..],
            "'--record-format <FORMAT>'",
        ),
        (&["run", "--replay", "fast"][..], "'--replay <PACE>'"),
        (&["run", "--stage-cpus", "all"][..], "'--stage-cpus <CPUS>'"),
        // The set chosen per frame: one object, both databases named.
        (
            &["run", "--smoothing", "auto", "--objects", "fruitbox,can"][..],
            "auto is for one object",
        ),
        (
            &["run", "--smoothing", "auto", "--db", "sharp.acchdb"][..],
            "smoothed_db",
        ),
        (
            &[
                "train",
                "--object",
                "can",
                "--smoothing",
                "auto",
                "--out",
                "x.acchdb",
            ][..],
            "--smoothing auto chooses between two databases",
        ),
        (
            &["eval", "--protocol", "table1", "--smoothing", "auto"][..],
            "--smoothing auto",
        ),
        // A mesh file given as a built-in name: the option it needs.
        (
            &["eval", "--protocol", "table2", "--object", "../duck.obj"][..],
            "a mesh file is read with --mesh ../duck.obj",
        ),
        // Refused before any database is trained.
        (
            &[
                "run",
                "--confidence-imaging",
                "--light-directions",
                "8",
                "--frames",
                "1",
            ][..],
            "--confidence-imaging and --light-directions",
        ),
        (
            &[
                "train",
                "--images",
                "nowhere",
                "--confidence-imaging",
                "--out",
                "x.acchdb",
            ][..],
            "--confidence-imaging",
        ),
        (
            &["eval", "--protocol", "robust", "--objects", "random:5000"][..],
            "random:5000",
        ),
        (
            &["run", "--in-process", "--objects", "fruitbox,random:99"][..],
            "random:99",
        ),
        (
            &[
                "eval",
                "--protocol",
                "multi",
                "--objects",
                "fruitbox",
                "--in-view",
                "0",
            ][..],
            "--in-view 0",
        ),
        (
            &["bench", "--objects", "fruitbox,can", "--known", "4"][..],
            "--known 4",
        ),
        (
            &[
                "train",
                "--object",
                "fruitbox",
                "--smoothing",
                "gaussian",
                "--out",
                "x.acchdb",
            ][..],
            "unknown smoothing 'gaussian'",
        ),
    ] {
        let out = acch(dir.path(), args);
        fails_naming(&out, what);
    }
}

/// A valid database: the cached default (trained on first use).
fn valid_database() -> &'static PathBuf {
    static DB: OnceLock<PathBuf> = OnceLock::new();
    DB.get_or_init(|| {
        let dir = tempfile::tempdir().unwrap();
        let cfg = dir.path().join("p.toml");
        std::fs::write(
            &cfg,
            format!(
                "[camera]\nframes = 3\nfps = 0.0\n[zenoh]\nlisten = [\"tcp/127.0.0.1:{}\"]\n",
                free_port()
            ),
        )
        .unwrap();
        let json = dir.path().join("run.json");
        let out = acch(
            dir.path(),
            &[
                "run",
                "--config",
                cfg.to_str().unwrap(),
                "--json",
                json.to_str().unwrap(),
            ],
        );
        assert!(
            out.status.success(),
            "{}",
            String::from_utf8_lossy(&out.stderr)
        );
        // The file this build's run trained or loaded, not any fruitbox
        // database another build left in the shared cache.
        let object = acch_capture::Object::builtin("fruitbox").unwrap();
        let path = acch_train::cache::cached_database_path(&object, None, false);
        assert!(path.exists(), "{} was not cached", path.display());
        path
    })
}

#[test]
fn missing_corrupt_truncated_and_wrong_version_databases_name_the_file() {
    let good = std::fs::read(valid_database()).unwrap();
    let dir = tempfile::tempdir().unwrap();
    let mut cases: Vec<(&str, Vec<u8>, &str)> = vec![
        (
            "garbage.acchdb",
            b"definitely not a database".to_vec(),
            "not an acch view database",
        ),
        (
            "truncated.acchdb",
            good[..good.len() / 2].to_vec(),
            "truncated",
        ),
        ("empty.acchdb", Vec::new(), "not an acch view database"),
    ];
    let mut flipped = good.clone();
    let mid = flipped.len() / 2;
    flipped[mid] ^= 0x5a;
    cases.push(("flipped.acchdb", flipped, "checksum"));
    let mut version = good.clone();
    version[8..12].copy_from_slice(&99u32.to_le_bytes());
    cases.push(("version99.acchdb", version, "version 99"));
    for (name, bytes, why) in &cases {
        let path = dir.path().join(name);
        std::fs::write(&path, bytes).unwrap();
        let out = acch(
            dir.path(),
            &["run", "--frames", "3", "--db", path.to_str().unwrap()],
        );
        let err = fails_naming(&out, name);
        assert!(
            err.to_lowercase().contains(why),
            "{name}: expected '{why}': {err}"
        );
    }
    let out = acch(
        dir.path(),
        &[
            "run",
            "--frames",
            "3",
            "--db",
            dir.path().join("absent.acchdb").to_str().unwrap(),
        ],
    );
    fails_naming(&out, "absent.acchdb");
}

/// Renders `views` of the fruitbox at `w` x `h` into `out` (PNG +
/// labels.csv).
fn render(out: &Path, views: &str, w: u32, h: u32) {
    let o = Command::new(env!("CARGO_BIN_EXE_acch"))
        .args([
            "render",
            "--object",
            "fruitbox",
            "--background",
            "A",
            "--views",
            views,
        ])
        .args([
            "--width",
            &w.to_string(),
            "--height",
            &h.to_string(),
            "--out",
        ])
        .arg(out)
        .output()
        .unwrap();
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
}

fn folder_run(dir: &Path, folder: &Path, frames: u32) -> Output {
    let json = dir.join("run.json");
    let cfg = dir.join("p.toml");
    std::fs::write(
        &cfg,
        format!(
            "[camera]\nsource = \"folder:{}\"\nframes = {frames}\nfps = 30.0\n\
             [zenoh]\nlisten = [\"tcp/127.0.0.1:{}\"]\n",
            folder.display(),
            free_port()
        ),
    )
    .unwrap();
    acch(
        dir,
        &[
            "run",
            "--config",
            cfg.to_str().unwrap(),
            "--json",
            json.to_str().unwrap(),
        ],
    )
}

#[test]
fn missing_corrupt_and_truncated_images_name_the_file() {
    valid_database();
    let dir = tempfile::tempdir().unwrap();
    let imgs = dir.path().join("imgs");
    render(&imgs, "grid:60,80:90", 320, 240);
    let labels = std::fs::read_to_string(imgs.join("labels.csv")).unwrap();
    let mut lines: Vec<&str> = labels.lines().collect();
    let files: Vec<String> = lines[1..]
        .iter()
        .map(|l| l.split(',').next().unwrap().to_string())
        .collect();
    assert!(files.len() >= 4, "{labels}");

    // Missing: labels.csv lists a file that is not there.
    let missing = lines[2].replacen(&files[1], "gone.png", 1);
    lines[2] = &missing;
    std::fs::write(imgs.join("labels.csv"), lines.join("\n") + "\n").unwrap();
    names_cleanly(&folder_run(dir.path(), &imgs, 4), "gone.png");
    std::fs::write(imgs.join("labels.csv"), &labels).unwrap();

    // Corrupt: not a PNG at all.
    let victim = imgs.join(&files[2]);
    let good = std::fs::read(&victim).unwrap();
    std::fs::write(&victim, b"this is not an image").unwrap();
    names_cleanly(&folder_run(dir.path(), &imgs, 4), &files[2]);

    // Truncated: the first half of a PNG.
    std::fs::write(&victim, &good[..good.len() / 2]).unwrap();
    names_cleanly(&folder_run(dir.path(), &imgs, 4), &files[2]);

    // A labels.csv with a bad number names the file and the line.
    std::fs::write(&victim, &good).unwrap();
    let mut bad: Vec<String> = labels.lines().map(str::to_owned).collect();
    let mut f: Vec<&str> = bad[2].split(',').collect();
    f[1] = "forty-five";
    bad[2] = f.join(",");
    std::fs::write(imgs.join("labels.csv"), bad.join("\n") + "\n").unwrap();
    // file:line, the column and the value.
    let err = fails_naming(&folder_run(dir.path(), &imgs, 4), "labels.csv:3");
    assert!(err.contains("forty-five"), "{err}");
}

#[test]
fn frames_of_another_size_mid_stream_are_skipped_and_the_rest_estimated() {
    valid_database();
    let dir = tempfile::tempdir().unwrap();
    let (big, small, mixed) = (
        dir.path().join("big"),
        dir.path().join("small"),
        dir.path().join("mixed"),
    );
    render(&big, "grid:60,80:60", 640, 480);
    render(&small, "grid:70:120", 320, 240);
    std::fs::create_dir(&mixed).unwrap();
    // Interleave: every third frame has the other size.
    let read = |d: &Path| -> (String, Vec<String>) {
        let t = std::fs::read_to_string(d.join("labels.csv")).unwrap();
        let mut l = t.lines().map(str::to_owned);
        (l.next().unwrap(), l.collect())
    };
    let (header, big_rows) = read(&big);
    let (_, small_rows) = read(&small);
    let mut rows = Vec::new();
    let (mut b, mut s) = (big_rows.iter(), small_rows.iter());
    let mut k = 0;
    loop {
        let (src, row) = if k % 3 == 2 {
            match s.next() {
                Some(r) => (&small, r),
                None => break,
            }
        } else {
            match b.next() {
                Some(r) => (&big, r),
                None => break,
            }
        };
        let file = row.split(',').next().unwrap();
        let name = format!("{k:03}.png");
        std::fs::copy(src.join(file), mixed.join(&name)).unwrap();
        rows.push(row.replacen(file, &name, 1));
        k += 1;
    }
    std::fs::write(
        mixed.join("labels.csv"),
        format!("{header}\n{}\n", rows.join("\n")),
    )
    .unwrap();
    let n = rows.len() as u64;
    let small: Vec<bool> = (0..rows.len()).map(|k| k % 3 == 2).collect();
    // The folder is cycled until n frames of the stream's size went out:
    // the frames it skips on the way.
    let (mut sent, mut expect_skipped, mut k) = (0u64, 0u64, 0usize);
    while sent < n {
        if small[k % rows.len()] {
            expect_skipped += 1;
        } else {
            sent += 1;
        }
        k += 1;
    }
    let out = folder_run(dir.path(), &mixed, n as u32);
    let err = String::from_utf8_lossy(&out.stderr);
    eprintln!("{err}");
    assert!(
        out.status.success(),
        "a run with frames of another size failed: {err}"
    );
    assert!(!err.contains("panicked"));
    let s: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(dir.path().join("run.json")).unwrap())
            .unwrap();
    eprintln!(
        "results {} of {n}, estimated {}, accepted {}, rejected {}, wrong {}",
        s["results"], s["estimated"], s["accepted"], s["rejected"], s["accepted_wrong"]
    );
    for (k, _) in small.iter().enumerate().filter(|(_, s)| **s) {
        let name = format!("{k:03}.png");
        assert!(
            err.contains(&name),
            "the skipped {name} is not named: {err}"
        );
    }
    // The rest estimated: every frame of the stream's size has a result,
    // every one of them an estimate, each rated one way or the other.
    assert_eq!(s["results"], n, "{s}");
    assert_eq!(s["estimated"], n, "{s}");
    assert_eq!(
        s["accepted"].as_u64().unwrap() + s["rejected"].as_u64().unwrap(),
        n,
        "{s}"
    );
    assert_eq!(s["accepted_wrong"], 0, "{s}");
    assert_eq!(s["faulted"], 0, "{s}");
    // The skips are counted where they happened, not only logged.
    let capture = s["stage_counters"]
        .as_array()
        .unwrap()
        .iter()
        .find(|c| c["stage"] == "capture")
        .unwrap_or_else(|| panic!("no capture counters: {s}"));
    assert_eq!(capture["skipped_size"], expect_skipped, "{capture}");
    assert_eq!(capture["sent"], n, "{capture}");
}

/// Every command prints each cause of an error once: a library error whose
/// message holds its source was printed again as the next cause ("No such
/// file or directory (os error 2): No such file or directory (os error 2)").
#[test]
fn each_command_says_each_cause_of_an_error_once() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let missing = d.join("missing.acchdb");
    let missing = missing.to_str().unwrap();
    let image = d.join("missing.png");
    let image = image.to_str().unwrap();
    let config = d.join("missing.toml");
    let config = config.to_str().unwrap();
    let mesh = d.join("missing.obj");
    let mesh = mesh.to_str().unwrap();
    let out_db = d.join("out.acchdb");
    let out_db = out_db.to_str().unwrap();
    let cases: [(&[&str], &str); 6] = [
        (&["estimate", "--db", missing, image], "No such file"),
        (
            &["run", "--objects", "nosuchobject", "--frames", "1"],
            "nosuchobject",
        ),
        (
            &["run", "--config", config, "--frames", "1"],
            "No such file",
        ),
        (&["train", "--mesh", mesh, "--out", out_db], "No such file"),
        (
            &["render", "--mesh", mesh, "--out", d.to_str().unwrap()],
            "No such file",
        ),
        (&["eval", "--bop", image, "--object", "1"], "missing.png"),
    ];
    for (args, cause) in cases {
        let out = acch(d, args);
        assert!(!out.status.success(), "acch {args:?} succeeded");
        let err = String::from_utf8_lossy(&out.stderr);
        let line = err
            .lines()
            .find(|l| l.starts_with("error:"))
            .unwrap_or_else(|| panic!("acch {args:?}: no error line in {err}"));
        assert_eq!(
            line.matches(cause).count(),
            1,
            "acch {args:?} should say '{cause}' once: {line}"
        );
    }
}
