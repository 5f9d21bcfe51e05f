//! `acch bench --objects`: what each known object and each object in view
//! costs. For every pair (known, in view) a child `acch run --in-process
//! --objects ... --objects-in-view ...` at 640x480 and 30 fps, beside the
//! first object run alone as a single-object pipeline; one JSON report and
//! a plot of e2e latency against the objects known.

use super::*;

/// The frame size and rate of the target.
const RESOLUTION: (u32, u32) = (640, 480);
const FPS: f64 = 30.0;

/// Runs the several-objects benchmark over the objects of `list`.
pub(crate) fn run(args: &BenchArgs, list: &str) -> Result<()> {
    let names: Vec<&str> = list
        .split(',')
        .map(str::trim)
        .filter(|s| !s.is_empty())
        .collect();
    if names.is_empty() {
        return Err(BenchError::Input(format!(
            "--objects '{list}' names no object"
        )));
    }
    if let Some(k) = args.known.iter().find(|&&k| k == 0 || k > names.len()) {
        return Err(BenchError::Input(format!(
            "--known {k}: between 1 and the {} objects of --objects",
            names.len()
        )));
    }
    if args.in_view.contains(&0) {
        return Err(BenchError::Input("--in-view: at least 1".into()));
    }
    if args.warmup >= args.frames {
        return Err(BenchError::Input(format!(
            "--warmup {} leaves nothing to measure of --frames {}",
            args.warmup, args.frames
        )));
    }
    let tmp = std::env::temp_dir().join(format!("acch-bench-multi-{}", std::process::id()));
    std::fs::create_dir_all(&tmp).map_err(io_err(&tmp))?;
    let single = run_child(args, &tmp, &names[..1], None)?;
    let mut rows = Vec::new();
    let mut measured = Vec::new();
    for &known in &args.known {
        for &in_view in args.in_view.iter().filter(|&&v| v <= known) {
            let r = run_child(args, &tmp, &names[..known], Some(in_view))?;
            let mut row = figures(&r, args.frames, args.warmup);
            row["known"] = json!(known);
            row["in_view"] = json!(in_view);
            row["objects"] = r.summary["objects"].clone();
            measured.push((known, in_view, q_ms(&r.e2e, 0.5), q_ms(&r.e2e, 0.99)));
            rows.push(row);
        }
    }
    let _ = std::fs::remove_dir_all(&tmp);
    let single = figures(&single, args.frames, args.warmup);
    let report = json!({
        "machine": machine(),
        "command": std::env::args().collect::<Vec<_>>().join(" "),
        "resolution": format!("{}x{}", RESOLUTION.0, RESOLUTION.1),
        "fps": FPS,
        "frames": args.frames,
        "warmup_frames_per_run": args.warmup,
        "objects": names,
        "targets": {"known": 4, "in_view": 3, "e2e_p99_ms": 15.0, "dropped": 0},
        "single": single,
        "rows": rows,
    });
    for p in [&args.objects_json, &args.objects_png] {
        if let Some(d) = p.parent().filter(|d| !d.as_os_str().is_empty()) {
            std::fs::create_dir_all(d).map_err(io_err(d))?;
        }
    }
    let text = serde_json::to_string_pretty(&report).expect("the report serialises") + "\n";
    std::fs::write(&args.objects_json, text).map_err(io_err(&args.objects_json))?;
    plot_cost(&args.objects_png, &measured, &single)?;
    println!(
        "{:>6} {:>8} {:>9} {:>9} {:>9} {:>8}",
        "known", "in view", "e2e p50", "e2e p99", "e2e max", "dropped"
    );
    let line = |known: &str, in_view: &str, f: &Value| {
        println!(
            "{known:>6} {in_view:>8} {:>9.2} {:>9.2} {:>9.2} {:>8}",
            f["e2e_p50_ms"].as_f64().unwrap_or(0.0),
            f["e2e_p99_ms"].as_f64().unwrap_or(0.0),
            f["e2e_max_ms"].as_f64().unwrap_or(0.0),
            f["dropped"]
        );
    };
    line("single", "1", &single);
    for r in report["rows"].as_array().into_iter().flatten() {
        line(&r["known"].to_string(), &r["in_view"].to_string(), r);
    }
    eprintln!(
        "acch bench: wrote {} and {}",
        args.objects_json.display(),
        args.objects_png.display()
    );
    Ok(())
}

/// One child run: `objects` known, the first `in_view` in view; `None`
/// runs the first object as the single-object pipeline.
fn run_child(
    args: &BenchArgs,
    tmp: &Path,
    objects: &[&str],
    in_view: Option<usize>,
) -> Result<RunResult> {
    let tag = in_view.map_or("single".to_owned(), |v| format!("{}-{v}", objects.len()));
    let out = tmp.join(format!("multi-{tag}.json"));
    let mut cmd = Command::new(&args.exe);
    cmd.args(["run", "--in-process"])
        .args(["--frames", &args.frames.to_string()])
        .args(["--fps", &FPS.to_string()])
        .args([
            "--resolution",
            &format!("{}x{}", RESOLUTION.0, RESOLUTION.1),
        ])
        .args(["--seed", &args.seed.to_string()])
        .args(["--stage-cpus", &args.stage_cpus])
        .arg("--samples")
        .arg("--json")
        .arg(&out);
    let what = match in_view {
        Some(v) => {
            cmd.args(["--objects", &objects.join(",")])
                .args(["--objects-in-view", &v.to_string()]);
            format!("{} known, {v} in view", objects.len())
        }
        None => {
            cmd.args(["--object", objects[0]]);
            format!("{} alone", objects[0])
        }
    };
    eprintln!("acch bench: {what}, {} frames", args.frames);
    measure(args, "in-process", cmd, &out, what)
}

/// e2e p50 and p99 against the objects known, a line per number in view,
/// the single-object pipeline's as a dashed level.
fn plot_cost(path: &Path, rows: &[(usize, usize, f64, f64)], single: &Value) -> Result<()> {
    let e = draw_err;
    let known_max = rows.iter().map(|r| r.0).max().unwrap_or(1) as f64;
    let ymax = rows.iter().map(|r| r.3).fold(15.0, f64::max) * 1.1;
    let mut views: Vec<usize> = rows.iter().map(|r| r.1).collect();
    views.sort_unstable();
    views.dedup();
    let single_p99 = single["e2e_p99_ms"].as_f64().unwrap_or(0.0);
    Ok(draw_png(path, (900, 550), |root| {
        let mut chart = ChartBuilder::on(root)
            .caption(
                "e2e latency against objects known (640x480, 30 fps, 2 cores)",
                ("sans-serif", 18),
            )
            .margin(12)
            .x_label_area_size(40)
            .y_label_area_size(50)
            .build_cartesian_2d(0.5f64..known_max + 0.5, 0.0f64..ymax)
            .map_err(e)?;
        chart
            .configure_mesh()
            .x_desc("objects known")
            .y_desc("ms")
            .draw()
            .map_err(e)?;
        for (i, &v) in views.iter().enumerate() {
            let colour = Palette99::pick(i).to_rgba();
            let pts = |q: fn(&(usize, usize, f64, f64)) -> f64| {
                rows.iter()
                    .filter(|r| r.1 == v)
                    .map(move |r| (r.0 as f64, q(r)))
                    .collect::<Vec<_>>()
            };
            chart
                .draw_series(LineSeries::new(pts(|r| r.3), colour.stroke_width(2)))
                .map_err(e)?
                .label(format!("{v} in view, p99"))
                .legend(move |(x, y)| PathElement::new(vec![(x, y), (x + 15, y)], colour));
            chart
                .draw_series(LineSeries::new(pts(|r| r.2), colour.stroke_width(1)))
                .map_err(e)?
                .label(format!("{v} in view, p50"))
                .legend(move |(x, y)| PathElement::new(vec![(x, y), (x + 15, y)], colour));
            chart
                .draw_series(
                    pts(|r| r.3)
                        .into_iter()
                        .map(|p| Circle::new(p, 3, colour.filled())),
                )
                .map_err(e)?;
        }
        for (level, name, colour) in [
            (15.0, "target p99 15 ms".to_owned(), RED.to_rgba()),
            (single_p99, "single-object p99".to_owned(), BLACK.to_rgba()),
        ] {
            chart
                .draw_series(LineSeries::new(
                    [(0.5, level), (known_max + 0.5, level)],
                    colour.stroke_width(1),
                ))
                .map_err(e)?
                .label(name)
                .legend(move |(x, y)| PathElement::new(vec![(x, y), (x + 15, y)], colour));
        }
        chart
            .configure_series_labels()
            .position(SeriesLabelPosition::UpperLeft)
            .background_style(WHITE.mix(0.8))
            .border_style(BLACK)
            .label_font(("sans-serif", 11))
            .draw()
            .map_err(e)?;
        Ok(())
    })?)
}
