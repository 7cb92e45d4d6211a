//! One hop between two processes on this machine: how long a 512-byte message takes from a
//! sender's `send` to the receiver having it in hand, for each way the pipeline could wake a
//! node.
//!
//! ```sh
//! cargo bench -p icrflow-runtime --bench hop [-- --seconds N]
//! ```
//!
//! The binary is the sender; for every cell of the table it starts itself again (hidden
//! argument [`RECEIVER`]) as the receiving process, on a private iceoryx2 prefix and root
//! directory that are removed at the end. Modes, i.e. how a message is carried and how its
//! receiver waits (the sender waits for echoes the same way):
//!
//! - `iox2-poll`: raw iceoryx2 publish-subscribe, the receiver busy-polls
//!   `Subscriber::receive` (iceoryx2's own benchmark style);
//! - `iox2-event`: the project's bus, [`Pub::send`] publishes and notifies, the receiver
//!   sleeps in `ppoll(2)` on the topic's listener ([`Waiter`]) and then drains [`Sub`] (how
//!   the nodes wake, `icrflow_runtime::event::serve`);
//! - `iox2-waitset`: the same, but the receiver sleeps in an iceoryx2 WaitSet (how the nodes
//!   woke until session 10);
//! - `spin-then-block-Wus`: the same bus, but after each message the receiver keeps polling
//!   [`Sub::drain`] for a window W before it goes back to sleep in the [`Waiter`];
//! - `uds`: a Unix datagram socket, blocking `recv`.
//!
//! Patterns: `ping-pong` sends back-to-back round trips (the receiver echoes over a second
//! channel of the same mode) and reports round trip / 2, as iceoryx2's benchmark does;
//! `1kHz` sends one message every millisecond, sleeping in between like the pipeline's loop,
//! and reports receive time - send time, the send time travelling in the payload as
//! `CLOCK_MONOTONIC` nanoseconds (one clock for all processes of the machine). Each cell
//! discards [`WARM_UP`], then measures for `--seconds` (3 by default). `1kHz` messages that
//! never arrived (a receiver queue overflowed) are counted below the table.
//!
//! Not criterion: a sample here needs a second process, and the figures that matter are tail
//! percentiles of single hops, not a mean with confidence intervals. Run without `--bench`
//! (`cargo test --benches`), every cell runs briefly as a smoke test.

#![allow(
    clippy::unwrap_used,
    clippy::expect_used,
    reason = "a test, bench or example: a panic is its failure, with the message it gives"
)]

use std::collections::VecDeque;
use std::fmt;
use std::io::{BufRead as _, BufReader, Read as _, Write as _};
use std::os::unix::net::UnixDatagram;
use std::path::{Path, PathBuf};
use std::process::{Child, ChildStdout, Command, ExitCode, Stdio};
use std::str::FromStr;
use std::time::{Duration, Instant};

use anyhow::{Context as _, Result, bail, ensure};
use iceoryx2::port::publisher::Publisher;
use iceoryx2::port::subscriber::Subscriber;
use iceoryx2::prelude::*;
use iceoryx2::waitset::WaitSetRunResult;
use icrflow_runtime::bus::{Bus, BusConfig, Pub, Sub};
use icrflow_runtime::event::Waiter;
use nix::time::{ClockId, clock_gettime};

/// The message: a send time and a tag in its first bytes, zeros after.
type Payload = [u8; PAYLOAD];
/// Message size in bytes.
const PAYLOAD: usize = 512;
/// Hidden first argument that makes the binary the receiving process.
const RECEIVER: &str = "--hop-receiver";
/// The line the receiver prints once its ports exist.
const READY: &str = "ready";
/// Rig name of the private bus (topics are `icrflow/hop/<mode>-<pattern>-<ping|pong>`).
const RIG: &str = "hop";
/// Time each cell runs before it records samples.
const WARM_UP: Duration = Duration::from_millis(300);
/// Measured time per cell with `--bench`, and without it (smoke test).
const SECONDS: f64 = 3.0;
const SMOKE_SECONDS: f64 = 0.1;
/// The `1kHz` pattern's send period.
const PERIOD: Duration = Duration::from_millis(1);
/// A side that hears nothing for this long gives up (its peer died).
const RECV_TIMEOUT: Duration = Duration::from_secs(10);
/// Messages a raw iceoryx2 subscriber keeps queued, as many as the bus's (oldest dropped).
const QUEUE: usize = 8;
/// Busy-poll iterations between two looks at the clock for [`RECV_TIMEOUT`].
const POLLS_PER_CLOCK_READ: u32 = 1024;

/// The table's rows, in order: every pattern of every mode.
const MODES: [Mode; 6] = [
    Mode::Poll,
    Mode::Event,
    Mode::WaitSet,
    Mode::SpinThenBlock(Duration::from_micros(50)),
    Mode::SpinThenBlock(Duration::from_micros(200)),
    Mode::Uds,
];
const PATTERNS: [Pattern; 2] = [Pattern::PingPong, Pattern::Rate1k];

fn main() -> ExitCode {
    set_log_level(LogLevel::Warn);
    let args: Vec<String> = std::env::args().skip(1).collect();
    let result = match args.split_first() {
        Some((first, rest)) if first == RECEIVER => receiver_main(rest),
        _ => sender_main(&args),
    };
    match result {
        Ok(()) => ExitCode::SUCCESS,
        Err(e) => {
            eprintln!("hop: error: {e:#}");
            ExitCode::FAILURE
        }
    }
}

/// The sender: every cell in turn, one table row each, then the run's files removed.
fn sender_main(args: &[String]) -> Result<()> {
    let measure = parse_seconds(args)?;
    let pid = std::process::id();
    let cfg = BusConfig::new(
        RIG,
        &format!("hop{pid}_"),
        PathBuf::from(format!("/tmp/icrflow/hop-{pid}")),
    )?;
    std::fs::create_dir_all(&cfg.root)
        .with_context(|| format!("creating {}", cfg.root.display()))?;
    let result = run_cells(&cfg, measure);
    cfg.remove_files();
    let left = cfg.leftovers();
    if result.is_ok() && !left.is_empty() {
        bail!("the run's iceoryx2 files could not all be removed: {left:?}");
    }
    result
}

/// `--seconds N` (measured time per cell); `--bench` is cargo's.
fn parse_seconds(args: &[String]) -> Result<Duration> {
    const USAGE: &str = "usage: cargo bench -p icrflow-runtime --bench hop [-- --seconds N]";
    let mut seconds = None;
    let mut bench = false;
    let mut it = args.iter();
    while let Some(arg) = it.next() {
        match arg.as_str() {
            "--bench" => bench = true,
            "--seconds" => {
                let value = it.next().context(USAGE)?;
                seconds = Some(
                    value
                        .parse()
                        .with_context(|| format!("--seconds {value:?}"))?,
                );
            }
            other => bail!("unknown argument {other:?}; {USAGE}"),
        }
    }
    let seconds = seconds.unwrap_or(if bench { SECONDS } else { SMOKE_SECONDS });
    Duration::try_from_secs_f64(seconds)
        .ok()
        .filter(|d| !d.is_zero())
        .with_context(|| format!("--seconds {seconds}: give a positive number"))
}

fn run_cells(cfg: &BusConfig, measure: Duration) -> Result<()> {
    let bus = Bus::new("hop-sender", cfg)?;
    let timing = Timing { measure };
    println!(
        "one hop between two processes, {PAYLOAD}-byte payload; {:.1} s per cell after a \
         {WARM_UP:?} warm-up; ping-pong: round trip / 2; 1kHz: receive - send time",
        measure.as_secs_f64()
    );
    println!("load average at start: {}", load_average());
    println!("| mode | pattern | samples | p50 (us) | p99 (us) | max (us) |");
    println!("|---|---|--:|--:|--:|--:|");
    let mut losses = Vec::new();
    for mode in MODES {
        for pattern in PATTERNS {
            let cell = Cell { mode, pattern };
            let (samples, sent) =
                measure_cell(&bus, cell, timing).with_context(|| cell.to_string())?;
            if samples.len() < sent {
                losses.push(format!(
                    "{mode} {pattern}: received {} of {sent}",
                    samples.len()
                ));
            }
            println!("| {mode} | {pattern} | {} |", Summary::of(samples)?);
        }
    }
    for loss in losses {
        println!("lost messages, {loss}");
    }
    Ok(())
}

/// The first three fields of /proc/loadavg.
fn load_average() -> String {
    std::fs::read_to_string("/proc/loadavg").map_or_else(
        |e| format!("unknown ({e})"),
        |s| s.split_whitespace().take(3).collect::<Vec<_>>().join(" "),
    )
}

/// One cell's samples in nanoseconds and the number of measured messages sent: starts the
/// receiver, runs the pattern, collects.
fn measure_cell(bus: &Bus, cell: Cell, timing: Timing) -> Result<(Vec<u64>, usize)> {
    with_link(bus, cell, Side::Sender, |link| {
        let mut receiver = Receiver::spawn(bus.config(), cell)?;
        match cell.pattern {
            Pattern::PingPong => {
                let samples = ping_pong(link, timing)?;
                receiver.finish()?;
                let sent = samples.len();
                Ok((samples, sent))
            }
            Pattern::Rate1k => {
                let sent = send_at_1khz(link, timing)?;
                Ok((receiver.finish()?, sent))
            }
        }
    })
}

/// The receiving process: echoes (`ping-pong`) or prints the one-way latencies it saw
/// (`1kHz`), one per line in nanoseconds.
fn receiver_main(args: &[String]) -> Result<()> {
    let [mode, pattern, rig, prefix, root] = args else {
        bail!("usage: hop {RECEIVER} MODE PATTERN RIG PREFIX ROOT (started by the hop bench)");
    };
    let cell = Cell {
        mode: mode.parse()?,
        pattern: pattern.parse()?,
    };
    let bus = Bus::new(
        "hop-receiver",
        &BusConfig::new(rig, prefix, PathBuf::from(root))?,
    )?;
    with_link(&bus, cell, Side::Receiver, |link| {
        println!("{READY}");
        match cell.pattern {
            Pattern::PingPong => echo(link),
            Pattern::Rate1k => {
                let samples = one_way(link)?;
                let mut out = std::io::stdout().lock();
                samples.iter().try_for_each(|s| writeln!(out, "{s}"))?;
                Ok(())
            }
        }
    })
}

/// The sender's back-to-back round trips; round trip / 2 of each measured one.
fn ping_pong(link: &mut dyn Link, timing: Timing) -> Result<Vec<u64>> {
    let start = Instant::now();
    let mut samples = Vec::new();
    while let Some(tag) = timing.tag(start.elapsed()) {
        let stamp = Stamp::now(tag);
        link.send(&stamp.encode())?;
        let echo = Stamp::decode(&link.recv()?)?;
        ensure!(echo.sent == stamp.sent, "echo of another message");
        if tag == Tag::Measured {
            samples.push((now_ns() - stamp.sent) / 2);
        }
    }
    link.send(&Stamp::now(Tag::Stop).encode())?;
    Ok(samples)
}

/// The sender's messages, one per [`PERIOD`], sleeping in between; how many were measured.
/// A sender that wakes more than a period late does not catch up with a burst: the schedule
/// slips instead.
fn send_at_1khz(link: &mut dyn Link, timing: Timing) -> Result<usize> {
    let start = Instant::now();
    let mut next = start;
    let mut measured = 0;
    while let Some(tag) = timing.tag(start.elapsed()) {
        link.send(&Stamp::now(tag).encode())?;
        measured += usize::from(tag == Tag::Measured);
        let now = Instant::now();
        next += PERIOD;
        if next < now {
            next = now + PERIOD;
        }
        std::thread::sleep(next - now);
    }
    link.send(&Stamp::now(Tag::Stop).encode())?;
    Ok(measured)
}

/// The receiver's side of `ping-pong`: sends every message back until told to stop.
fn echo(link: &mut dyn Link) -> Result<()> {
    loop {
        let payload = link.recv()?;
        if Stamp::decode(&payload)?.tag == Tag::Stop {
            return Ok(());
        }
        link.send(&payload)?;
    }
}

/// The receiver's side of `1kHz`: receive time - send time of every measured message.
fn one_way(link: &mut dyn Link) -> Result<Vec<u64>> {
    let mut samples = Vec::new();
    loop {
        let payload = link.recv()?;
        let received = now_ns();
        let stamp = Stamp::decode(&payload)?;
        match stamp.tag {
            Tag::Stop => return Ok(samples),
            Tag::Measured => samples.push(received.saturating_sub(stamp.sent)),
            Tag::WarmUp => {}
        }
    }
}

/// `CLOCK_MONOTONIC` in nanoseconds: unlike [`Instant`], a reading another process can
/// compare with its own.
fn now_ns() -> u64 {
    let t = clock_gettime(ClockId::CLOCK_MONOTONIC)
        .expect("CLOCK_MONOTONIC is always readable on Linux");
    Duration::from(t).as_nanos() as u64
}

/// What a message is for.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
enum Tag {
    WarmUp = 0,
    Measured = 1,
    Stop = 2,
}

/// The header a message carries: its tag and its send time ([`now_ns`]).
#[derive(Debug, Clone, Copy)]
struct Stamp {
    tag: Tag,
    sent: u64,
}

impl Stamp {
    /// A message of `tag` sent now.
    fn now(tag: Tag) -> Self {
        Self {
            tag,
            sent: now_ns(),
        }
    }

    fn encode(self) -> Payload {
        let mut payload = [0; PAYLOAD];
        payload[..8].copy_from_slice(&self.sent.to_ne_bytes());
        payload[8] = self.tag as u8;
        payload
    }

    fn decode(payload: &Payload) -> Result<Self> {
        let mut sent = [0; 8];
        sent.copy_from_slice(&payload[..8]);
        let tag = match payload[8] {
            0 => Tag::WarmUp,
            1 => Tag::Measured,
            2 => Tag::Stop,
            other => bail!("message with unknown tag {other}"),
        };
        Ok(Self {
            tag,
            sent: u64::from_ne_bytes(sent),
        })
    }
}

/// How long a cell runs: [`WARM_UP`], then `measure`.
#[derive(Debug, Clone, Copy)]
struct Timing {
    measure: Duration,
}

impl Timing {
    /// The tag of a message sent `elapsed` after the cell started; `None` when it is over.
    fn tag(self, elapsed: Duration) -> Option<Tag> {
        if elapsed < WARM_UP {
            Some(Tag::WarmUp)
        } else if elapsed < WARM_UP + self.measure {
            Some(Tag::Measured)
        } else {
            None
        }
    }
}

/// How messages travel and how a receiver waits for them.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
enum Mode {
    Poll,
    Event,
    WaitSet,
    SpinThenBlock(Duration),
    Uds,
}

impl fmt::Display for Mode {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            Self::Poll => f.write_str("iox2-poll"),
            Self::Event => f.write_str("iox2-event"),
            Self::WaitSet => f.write_str("iox2-waitset"),
            Self::SpinThenBlock(w) => write!(f, "spin-then-block-{}us", w.as_micros()),
            Self::Uds => f.write_str("uds"),
        }
    }
}

impl FromStr for Mode {
    type Err = anyhow::Error;

    fn from_str(s: &str) -> Result<Self> {
        let spin = |s: &str| {
            let us = s.strip_prefix("spin-then-block-")?.strip_suffix("us")?;
            us.parse().ok().map(Duration::from_micros)
        };
        Ok(match s {
            "iox2-poll" => Self::Poll,
            "iox2-event" => Self::Event,
            "iox2-waitset" => Self::WaitSet,
            "uds" => Self::Uds,
            _ => Self::SpinThenBlock(spin(s).with_context(|| format!("unknown mode {s:?}"))?),
        })
    }
}

/// What the sender sends when.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
enum Pattern {
    PingPong,
    Rate1k,
}

impl fmt::Display for Pattern {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(match self {
            Self::PingPong => "ping-pong",
            Self::Rate1k => "1kHz",
        })
    }
}

impl FromStr for Pattern {
    type Err = anyhow::Error;

    fn from_str(s: &str) -> Result<Self> {
        match s {
            "ping-pong" => Ok(Self::PingPong),
            "1kHz" => Ok(Self::Rate1k),
            _ => bail!("unknown pattern {s:?}"),
        }
    }
}

/// One row of the table.
#[derive(Debug, Clone, Copy)]
struct Cell {
    mode: Mode,
    pattern: Pattern,
}

impl fmt::Display for Cell {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(f, "{}-{}", self.mode, self.pattern)
    }
}

impl Cell {
    /// The cell's own channel `direction` (`ping`: sender to receiver, `pong`: back).
    fn channel(self, direction: &str) -> String {
        format!("{self}-{direction}")
    }
}

/// Which end of the hop this process is.
#[derive(Debug, Clone, Copy)]
enum Side {
    Sender,
    Receiver,
}

impl Side {
    /// The channels this side sends on and receives from.
    fn directions(self) -> (&'static str, &'static str) {
        match self {
            Self::Sender => ("ping", "pong"),
            Self::Receiver => ("pong", "ping"),
        }
    }
}

/// One side's two channels.
trait Link {
    fn send(&mut self, payload: &Payload) -> Result<()>;
    /// The next message, waiting for it in the mode's way.
    fn recv(&mut self) -> Result<Payload>;
}

/// Opens `side`'s link of `cell` and runs `body` on it.
fn with_link<T>(
    bus: &Bus,
    cell: Cell,
    side: Side,
    body: impl FnOnce(&mut dyn Link) -> Result<T>,
) -> Result<T> {
    let (out, inc) = side.directions();
    let (out, inc) = (cell.channel(out), cell.channel(inc));
    match cell.mode {
        Mode::Poll => body(&mut PollLink::new(bus, &out, &inc)?),
        Mode::Event => with_bus_link(bus, &out, &inc, Duration::ZERO, false, body),
        Mode::WaitSet => with_bus_link(bus, &out, &inc, Duration::ZERO, true, body),
        Mode::SpinThenBlock(window) => with_bus_link(bus, &out, &inc, window, false, body),
        Mode::Uds => body(&mut UdsLink::new(&bus.config().root, &out, &inc)?),
    }
}

/// Raw iceoryx2 publish-subscribe; `recv` busy-polls.
struct PollLink {
    publisher: Publisher<ipc::Service, Payload, ()>,
    subscriber: Subscriber<ipc::Service, Payload, ()>,
}

impl PollLink {
    fn new(bus: &Bus, out: &str, inc: &str) -> Result<Self> {
        let service = |topic: &str| -> Result<_> {
            let name = bus.config().service(topic);
            let name = ServiceName::new(&name).map_err(|e| anyhow::anyhow!("{name}: {e:?}"))?;
            let service = bus
                .node()
                .service_builder(&name)
                .publish_subscribe::<Payload>()
                .subscriber_max_buffer_size(QUEUE)
                .open_or_create()?;
            Ok(service)
        };
        Ok(Self {
            publisher: service(out)?.publisher_builder().create()?,
            subscriber: service(inc)?
                .subscriber_builder()
                .buffer_size(QUEUE)
                .create()?,
        })
    }
}

impl Link for PollLink {
    fn send(&mut self, payload: &Payload) -> Result<()> {
        self.publisher
            .loan_uninit()?
            .write_payload(*payload)
            .send()?;
        Ok(())
    }

    fn recv(&mut self) -> Result<Payload> {
        let deadline = Instant::now() + RECV_TIMEOUT;
        loop {
            for _ in 0..POLLS_PER_CLOCK_READ {
                if let Some(sample) = self.subscriber.receive()? {
                    return Ok(*sample.payload());
                }
                std::hint::spin_loop();
            }
            ensure!(
                Instant::now() < deadline,
                "nothing received in {RECV_TIMEOUT:?}"
            );
        }
    }
}

/// The project's bus; `recv` polls for `spin` after the previous message, then sleeps until
/// notified.
struct BusLink<'a> {
    publisher: Pub<Payload>,
    subscriber: &'a Sub<Payload>,
    sleep: Sleep<'a>,
    spin: Duration,
    queue: VecDeque<Payload>,
}

/// How a [`BusLink`] sleeps on its subscriber's listener.
enum Sleep<'a> {
    /// `ppoll(2)` on its file descriptor (the nodes' way).
    Ppoll(Waiter<'a>),
    /// An iceoryx2 WaitSet with the listener attached.
    WaitSet(&'a WaitSet<ipc::Service>),
}

/// Opens a [`BusLink`] (sleeping in a [`Waiter`], or with `waitset` in an iceoryx2 WaitSet, on
/// its subscriber's listener) and runs `body` on it.
fn with_bus_link<T>(
    bus: &Bus,
    out: &str,
    inc: &str,
    spin: Duration,
    waitset: bool,
    body: impl FnOnce(&mut dyn Link) -> Result<T>,
) -> Result<T> {
    let subscriber = bus.subscriber_named(inc)?;
    let set = WaitSetBuilder::new().create::<ipc::Service>()?;
    let _attachment = if waitset {
        Some(set.attach_notification(subscriber.listener())?)
    } else {
        None
    };
    body(&mut BusLink {
        publisher: bus.publisher_named(out)?,
        subscriber: &subscriber,
        sleep: if waitset {
            Sleep::WaitSet(&set)
        } else {
            Sleep::Ppoll(Waiter::new(&[subscriber.listener()]))
        },
        spin,
        queue: VecDeque::new(),
    })
}

impl BusLink<'_> {
    /// Queues whatever has arrived, without blocking.
    fn poll(&mut self) -> Result<()> {
        self.subscriber.drain(|p| self.queue.push_back(*p))?;
        Ok(())
    }
}

impl Link for BusLink<'_> {
    fn send(&mut self, payload: &Payload) -> Result<()> {
        self.publisher.send(*payload)?;
        Ok(())
    }

    fn recv(&mut self) -> Result<Payload> {
        let start = Instant::now();
        loop {
            if let Some(payload) = self.queue.pop_front() {
                return Ok(payload);
            }
            if start.elapsed() < self.spin {
                self.poll()?;
                continue;
            }
            ensure!(
                start.elapsed() < RECV_TIMEOUT,
                "nothing received in {RECV_TIMEOUT:?}"
            );
            let woke = match &mut self.sleep {
                Sleep::Ppoll(waiter) => waiter.wait(RECV_TIMEOUT)?,
                Sleep::WaitSet(set) => !matches!(
                    set.wait_and_process_once_with_timeout(
                        |_| CallbackProgression::Continue,
                        RECV_TIMEOUT,
                    )?,
                    WaitSetRunResult::TerminationRequest | WaitSetRunResult::Interrupt
                ),
            };
            if !woke {
                bail!("interrupted");
            }
            self.poll()?;
        }
    }
}

/// A Unix datagram socket bound at `<root>/<incoming channel>.sock`, connected to the
/// peer's on the first send; `recv` blocks.
struct UdsLink {
    socket: UnixDatagram,
    peer: PathBuf,
    connected: bool,
}

impl UdsLink {
    fn new(root: &Path, out: &str, inc: &str) -> Result<Self> {
        let path = root.join(format!("{inc}.sock"));
        let socket =
            UnixDatagram::bind(&path).with_context(|| format!("binding {}", path.display()))?;
        socket.set_read_timeout(Some(RECV_TIMEOUT))?;
        Ok(Self {
            socket,
            peer: root.join(format!("{out}.sock")),
            connected: false,
        })
    }
}

impl Link for UdsLink {
    fn send(&mut self, payload: &Payload) -> Result<()> {
        if !self.connected {
            self.socket
                .connect(&self.peer)
                .with_context(|| format!("connecting to {}", self.peer.display()))?;
            self.connected = true;
        }
        let n = self.socket.send(payload)?;
        ensure!(n == PAYLOAD, "sent {n} of {PAYLOAD} bytes");
        Ok(())
    }

    fn recv(&mut self) -> Result<Payload> {
        let mut payload = [0; PAYLOAD];
        let n = self.socket.recv(&mut payload).context("receiving")?;
        ensure!(n == PAYLOAD, "received {n} of {PAYLOAD} bytes");
        Ok(payload)
    }
}

/// The receiving process of one cell; killed and reaped if dropped before it finished.
struct Receiver {
    child: Child,
    stdout: BufReader<ChildStdout>,
}

impl Receiver {
    /// Starts the receiver of `cell` and waits until its ports exist.
    fn spawn(cfg: &BusConfig, cell: Cell) -> Result<Self> {
        let exe = std::env::current_exe().context("locating the bench binary")?;
        let mut child = Command::new(exe)
            .args([RECEIVER, &cell.mode.to_string(), &cell.pattern.to_string()])
            .args([&cfg.rig, &cfg.prefix])
            .arg(&cfg.root)
            .stdin(Stdio::null())
            .stdout(Stdio::piped())
            .spawn()
            .context("starting the receiver")?;
        let stdout = child.stdout.take().context("the receiver's stdout")?;
        let mut receiver = Self {
            child,
            stdout: BufReader::new(stdout),
        };
        let mut line = String::new();
        receiver.stdout.read_line(&mut line)?;
        ensure!(
            line.trim() == READY,
            "the receiver exited before it was ready"
        );
        Ok(receiver)
    }

    /// Waits for the receiver to exit; the samples it printed.
    fn finish(&mut self) -> Result<Vec<u64>> {
        let mut text = String::new();
        self.stdout.read_to_string(&mut text)?;
        let status = self.child.wait()?;
        ensure!(status.success(), "the receiver failed ({status})");
        text.lines()
            .map(|l| l.parse().with_context(|| format!("receiver printed {l:?}")))
            .collect()
    }
}

impl Drop for Receiver {
    fn drop(&mut self) {
        if let Ok(None) = self.child.try_wait() {
            let _ = self.child.kill();
        }
        let _ = self.child.wait();
    }
}

/// A cell's row: sample count and percentiles in microseconds.
#[derive(Debug)]
struct Summary {
    samples: usize,
    p50: f64,
    p99: f64,
    max: f64,
}

impl Summary {
    fn of(mut ns: Vec<u64>) -> Result<Self> {
        ensure!(!ns.is_empty(), "no samples");
        ns.sort_unstable();
        // Nearest rank.
        let rank = |q: f64| ns[((q * ns.len() as f64).ceil() as usize).clamp(1, ns.len()) - 1];
        let us = |v: u64| v as f64 * 1e-3;
        Ok(Self {
            samples: ns.len(),
            p50: us(rank(0.50)),
            p99: us(rank(0.99)),
            max: us(rank(1.0)),
        })
    }
}

impl fmt::Display for Summary {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(
            f,
            "{} | {:.2} | {:.2} | {:.2}",
            self.samples, self.p50, self.p99, self.max
        )
    }
}
