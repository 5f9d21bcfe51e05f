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
//! # A stage's hop: one message per frame at 30 fps, each after 2 MB of work
//! cargo run --release -p acch-ipc --example hop_floor -- --same-cpu --rt 20 \
//!     --period-ms 33 --evict-kb 2048 --messages 300 --cpu-latency-us 0
//! ```
//!
//! At 1 kHz with nothing in between, both processes stay in the caches: that
//! is the warm floor. In the pipeline each hop follows milliseconds of a
//! stage's compute over megabytes, and the woken process has slept for most
//! of a frame period; `--period-ms` and `--evict-kb` (the publisher writes
//! that many kB before each send) reproduce that, so the difference between
//! the two floors is what cold caches and TLBs cost a hop on this machine.
//! `--cpu-latency-us` holds the kernel's CPU latency request for the
//! measurement (as `acch run --cpu-latency-us` does; needs root).
//!
//! The subscriber sleeps as a stage does, on the stream's wake-up word, a
//! futex in shared memory ([`acch_ipc::wake`]); `--socket` makes it sleep
//! on the iceoryx2 event (a Unix datagram socket) instead, as the launcher
//! and the observers do.
//!
//! `--same-cpu` puts both processes on the last allowed CPU (as
//! `stage_cpus = "auto"` does with the stages); `--rt P` runs the publisher
//! under SCHED_FIFO at P and the subscriber at P + 1 (as `--rt-priority`
//! does with the stages).

use acch_ipc::sched::{CpuLatencyRequest, allowed_cpus, pin_to, set_fifo};
use acch_ipc::{Ipc, StreamSpec, Wake, ZeroCopySend, now_ns};
use std::process::Command;
use std::time::Duration;

/// A header-only message, as small as a stage's result header needs.
#[repr(C)]
#[derive(Clone, Copy, Debug, Default, ZeroCopySend)]
struct Hop {
    sequence: u64,
    published_ns: u64,
}

/// A stage's result stream, sized as the pipeline sizes it.
const STREAM: StreamSpec = StreamSpec {
    name: "hop",
    subscribers: 4,
    buffer: 8,
    borrowed: 2,
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

/// The value after flag `name`, parsed, if the flag is given.
fn option<T: std::str::FromStr>(
    args: &[String],
    name: &str,
) -> Result<Option<T>, Box<dyn std::error::Error>>
where
    T::Err: std::error::Error + 'static,
{
    match args.iter().position(|a| a == name) {
        Some(i) => Ok(Some(
            args.get(i + 1)
                .ok_or_else(|| format!("{name} needs a value"))?
                .parse()?,
        )),
        None => Ok(None),
    }
}

fn main() -> Result<(), Box<dyn std::error::Error>> {
    let args: Vec<String> = std::env::args().collect();
    let same_cpu = args.iter().any(|a| a == "--same-cpu");
    let socket = args.iter().any(|a| a == "--socket");
    let rt: Option<u8> = option(&args, "--rt")?;
    let messages: usize = option(&args, "--messages")?.unwrap_or(2000);
    let period_ms: u64 = option(&args, "--period-ms")?.unwrap_or(1);
    let evict_kb: usize = option(&args, "--evict-kb")?.unwrap_or(0);
    if messages == 0 || period_ms == 0 {
        return Err("--messages and --period-ms must be at least 1".into());
    }
    let cpus = allowed_cpus()?;
    let (first, last) = (cpus[0], *cpus.last().ok_or("no CPU allowed")?);
    if let Some(i) = args.iter().position(|a| a == "--subscriber") {
        let (instance, cpu) = (&args[i + 1], args[i + 2].parse::<usize>()?);
        pin_to(&[cpu])?;
        if let Some(p) = rt {
            set_fifo(p + 1)?;
        }
        let ipc = Ipc::new(instance, "hop-subscriber")?;
        let input = ipc.input::<Hop>(STREAM, if socket { Wake::Event } else { Wake::Word })?;
        let mut latency = Vec::with_capacity(messages);
        while latency.len() < messages && ipc.keep_running() {
            input.wait(Duration::from_millis(200))?;
            while let Some(s) = input.receive()? {
                let sent = s.user_header().published_ns;
                latency.push(now_ns().saturating_sub(sent) as f64 / 1e3);
            }
        }
        println!("hop (send -> subscriber awake): {}", summary(latency));
        return Ok(());
    }
    if !same_cpu && first == last {
        return Err("only one CPU is allowed: use --same-cpu".into());
    }
    // Held by the publisher for the whole measurement, the subscriber's
    // included (the request is system-wide).
    let _latency = option::<u32>(&args, "--cpu-latency-us")?
        .map(CpuLatencyRequest::hold)
        .transpose()
        .map_err(|e| format!("--cpu-latency-us: {e} (needs root)"))?;
    pin_to(&[if same_cpu { last } else { first }])?;
    if let Some(p) = rt {
        set_fifo(p)?;
    }
    let instance = format!("hop-floor-{}", std::process::id());
    let ipc = Ipc::new(&instance, "hop-publisher")?;
    let output = ipc.output::<Hop>(STREAM, 64)?;
    let mut subscriber = Command::new(&args[0])
        .args(["--subscriber", &instance, &last.to_string()])
        .args(&args[1..])
        .spawn()?;
    // Time to connect; samples sent before would be lost to it.
    std::thread::sleep(Duration::from_millis(500));
    // A stage's working set: every cache line of it is written before each
    // send, as a stage's compute would.
    let mut work = vec![0u8; evict_kb * 1024];
    let mut cost = Vec::with_capacity(messages);
    for i in 0..messages {
        for (j, b) in work.iter_mut().enumerate().step_by(64) {
            *b = b.wrapping_add(i as u8 ^ j as u8);
        }
        std::hint::black_box(&work);
        let t0 = now_ns();
        output.send_in_place(0, |_, h| {
            h.sequence = i as u64;
            h.published_ns = now_ns();
            Ok::<(), std::convert::Infallible>(())
        })??;
        cost.push(now_ns().saturating_sub(t0) as f64 / 1e3);
        std::thread::sleep(Duration::from_millis(period_ms));
    }
    let status = subscriber.wait()?;
    acch_ipc::wake::remove_run(&instance);
    println!(
        "{}, {}, {}, every {period_ms} ms after {evict_kb} kB: send + notify: {}",
        if socket { "socket" } else { "futex word" },
        if same_cpu { "one CPU" } else { "two CPUs" },
        rt.map_or("normal scheduler".into(), |p| format!("SCHED_FIFO {p}")),
        summary(cost)
    );
    if !status.success() {
        return Err(format!("the subscriber failed: {status}").into());
    }
    Ok(())
}
