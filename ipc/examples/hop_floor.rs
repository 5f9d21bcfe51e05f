//! The floor of one pipeline hop on this machine: a publisher process sends
//! a header-only result message every millisecond through the pipeline's
//! own [`Output`](acch_ipc::Output) / [`Input`](acch_ipc::Input), the
//! subscriber process sleeps on the input's event, and the latency from
//! just before the send to the subscriber awake with the sample is
//! reported, with the publisher's own cost of send + notify.
//!
//! ```sh
//! cargo run --release -p acch-ipc --example hop_floor              # two CPUs
//! cargo run --release -p acch-ipc --example hop_floor -- --same-cpu
//! cargo run --release -p acch-ipc --example hop_floor -- --same-cpu --rt 20
//! cargo run --release -p acch-ipc --example hop_floor -- --same-cpu --socket
//! ```
//!
//! The subscriber sleeps as a stage does, on the stream's shared-memory
//! semaphore ([`Input::wait_blocking`](acch_ipc::Input::wait_blocking));
//! `--socket` makes it sleep on the Unix-datagram event instead, as the
//! launcher and the observers do (and the stages did before).
//!
//! `--same-cpu` puts both processes on the last allowed CPU (as
//! `stage_cpus = "auto"` does with the stages); `--rt P` runs the publisher
//! under SCHED_FIFO at P and the subscriber at P + 1 (as `--rt-priority`
//! does with the stages).

use acch_ipc::sched::{allowed_cpus, pin_to, set_fifo};
use acch_ipc::{Ipc, Names, Qos, ResultMsg, StageId, now_ns};
use std::process::Command;
use std::time::Duration;

const MESSAGES: usize = 2000;
const QOS: Qos = Qos {
    frame_history: 1,
    max_frame_bytes: 64,
};

/// p50, p90, p99 and max of `v` (microseconds), as one line.
fn summary(mut v: Vec<f64>) -> String {
    v.sort_by(f64::total_cmp);
    let q = |p: f64| v[((v.len() - 1) as f64 * p).round() as usize];
    format!(
        "p50 {:.1} µs, p90 {:.1} µs, p99 {:.1} µs, max {:.1} µs",
        q(0.5),
        q(0.9),
        q(0.99),
        q(1.0)
    )
}

fn main() -> Result<(), Box<dyn std::error::Error>> {
    let args: Vec<String> = std::env::args().collect();
    let same_cpu = args.iter().any(|a| a == "--same-cpu");
    let socket = args.iter().any(|a| a == "--socket");
    let rt: Option<u8> = match args.iter().position(|a| a == "--rt") {
        Some(i) => Some(args.get(i + 1).ok_or("--rt needs a priority")?.parse()?),
        None => None,
    };
    let cpus = allowed_cpus()?;
    let (first, last) = (cpus[0], *cpus.last().ok_or("no CPU allowed")?);
    if let Some(i) = args.iter().position(|a| a == "--subscriber") {
        let (instance, cpu) = (&args[i + 1], args[i + 2].parse::<usize>()?);
        pin_to(&[cpu])?;
        if let Some(p) = rt {
            set_fifo(p + 1)?;
        }
        let ipc = Ipc::new(Names::new(instance), "hop-subscriber", QOS)?;
        let input = if socket {
            ipc.result_input(StageId::Recognition)?
        } else {
            ipc.result_stage_input(StageId::Recognition)?
        };
        let mut latency = Vec::with_capacity(MESSAGES);
        while latency.len() < MESSAGES && ipc.keep_running() {
            input.wait_blocking(Duration::from_millis(200))?;
            while let Some(s) = input.receive()? {
                let sent = s.user_header().trail.stages[0].published_ns;
                latency.push(now_ns().saturating_sub(sent) as f64 / 1e3);
            }
        }
        println!("hop (send -> subscriber awake): {}", summary(latency));
        return Ok(());
    }
    if !same_cpu && first == last {
        return Err("only one CPU is allowed: use --same-cpu".into());
    }
    pin_to(&[if same_cpu { last } else { first }])?;
    if let Some(p) = rt {
        set_fifo(p)?;
    }
    let instance = format!("hop-floor-{}", std::process::id());
    let ipc = Ipc::new(Names::new(&instance), "hop-publisher", QOS)?;
    let output = ipc.result_output(StageId::Recognition, 64)?;
    let mut subscriber = Command::new(&args[0])
        .args(["--subscriber", &instance, &last.to_string()])
        .args(&args[1..])
        .spawn()?;
    // Time to connect; samples sent before would be lost to it.
    std::thread::sleep(Duration::from_millis(500));
    let mut cost = Vec::with_capacity(MESSAGES);
    for i in 0..MESSAGES {
        let t0 = now_ns();
        output.send_in_place(0, |_, h: &mut ResultMsg| {
            h.sequence = i as u64;
            h.trail.stages[0].published_ns = now_ns();
        })?;
        cost.push(now_ns().saturating_sub(t0) as f64 / 1e3);
        std::thread::sleep(Duration::from_millis(1));
    }
    let status = subscriber.wait()?;
    println!(
        "{}, {}, {}: send + notify: {}",
        if socket { "socket" } else { "semaphore" },
        if same_cpu { "one CPU" } else { "two CPUs" },
        rt.map_or("normal scheduler".into(), |p| format!("SCHED_FIFO {p}")),
        summary(cost)
    );
    if !status.success() {
        return Err(format!("the subscriber failed: {status}").into());
    }
    Ok(())
}
