//! The duck in every mesh format acch reads, converted by an independent
//! writer (trimesh, tests/convert_mesh.py): GLB with its texture embedded,
//! and PLY with vertex colours baked from the texture, binary and ASCII.
//! Each trains a database whose table-1 figures match the OBJ's within
//! 0.5°, and the OBJ's own figures meet a fixed bound.

mod common;

use common::ok;
use std::path::Path;
use std::process::Command;

const DUCK: &str = "/work/shared/data/duck/duck.obj";

fn table1(mesh: &Path, json: &Path) -> serde_json::Value {
    ok(&Command::new(env!("CARGO_BIN_EXE_acch"))
        .args([
            "eval",
            "--protocol",
            "table1",
            "--n",
            "120",
            "--seed",
            "4",
            "--mesh",
        ])
        .arg(mesh)
        .arg("--json")
        .arg(json)
        .env("RUST_LOG", "warn")
        .output()
        .unwrap());
    serde_json::from_str(&std::fs::read_to_string(json).unwrap()).unwrap()
}

#[test]
fn the_duck_as_glb_and_vertex_coloured_ply_trains_as_the_obj_does() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    ok(&Command::new("python3")
        .arg(Path::new(env!("CARGO_MANIFEST_DIR")).join("tests/convert_mesh.py"))
        .arg(DUCK)
        .arg(d)
        .output()
        .expect("python3 with trimesh (scripts/test installs it)"));
    let obj = table1(Path::new(DUCK), &d.join("obj.json"));
    // The baseline itself, on a fixed bound: measured 0.88° and 0.88°, no
    // failure, below the winner-takes-all floor of this grid (2.5°). A
    // broken OBJ reader would otherwise pass, the others matching it.
    for key in ["mean_phi_err_deg", "mean_theta_err_deg"] {
        let e = obj[key].as_f64().unwrap();
        assert!(e <= 2.0, "the OBJ's {key}: {e}°");
    }
    let failures = obj["failure_rate"].as_f64().unwrap();
    assert!(failures <= 0.02, "the OBJ's failures: {failures}");
    let mut rows = vec![("obj", obj.clone())];
    for (name, file) in [
        ("glb", "duck.glb"),
        ("ply", "duck_vc.ply"),
        ("ascii ply", "duck_vc_ascii.ply"),
    ] {
        let r = table1(&d.join(file), &d.join(format!("{file}.json")));
        for key in ["mean_phi_err_deg", "mean_theta_err_deg"] {
            let (a, b) = (obj[key].as_f64().unwrap(), r[key].as_f64().unwrap());
            assert!((a - b).abs() <= 0.5, "{name} {key}: {b} vs the OBJ's {a}");
        }
        let (a, b) = (
            obj["failure_rate"].as_f64().unwrap(),
            r["failure_rate"].as_f64().unwrap(),
        );
        assert!(
            (a - b).abs() <= 0.05,
            "{name} failures: {b} vs the OBJ's {a}"
        );
        rows.push((name, r));
    }
    for (name, r) in &rows {
        eprintln!(
            "{name:>10}: E(phi) {:.2}° E(theta) {:.2}° failures {:.1}%",
            r["mean_phi_err_deg"].as_f64().unwrap(),
            r["mean_theta_err_deg"].as_f64().unwrap(),
            100.0 * r["failure_rate"].as_f64().unwrap()
        );
    }
    // Binary and ASCII PLY are the same mesh: the same figures exactly.
    assert_eq!(rows[2].1["mean_phi_err_deg"], rows[3].1["mean_phi_err_deg"]);
    assert_eq!(rows[2].1["failure_rate"], rows[3].1["failure_rate"]);
}
