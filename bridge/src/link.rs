//! The loop topics between hosts: when `pipeline.nodes` runs only some of the nodes here, the
//! bridge carries the topics that cross ([`topics::links`]) as bytes ([`icrflow_interfaces::wire`])
//! on `icrflow/<rig>/link/<topic>`:
//! - **out** ([`Export`]): a topic published here and read on another host is taken off the
//!   local bus as soon as it is published (the bridge sleeps on its event, no polling) and put
//!   on Zenoh with congestion control `Block`, express, at real-time priority: the loop loses
//!   no message to a slow link (a link that stays blocked is closed by Zenoh, and the hand
//!   command node holds on the missing input);
//! - **in** ([`Importer`]): a topic read here and published on another host is received on a
//!   thread of its own, checked (format, schema version, kind, sizes, header) and published
//!   on the local bus exactly as it was sent: sequence numbers, times and trace included, so
//!   the receiving nodes check its order and age as for a local message. What fails a check
//!   is logged (once per reason) and counted in the bridge's health, never published.

use std::sync::Arc;
use std::sync::atomic::{AtomicBool, AtomicU64, Ordering};
use std::sync::mpsc;
use std::time::Duration;

use anyhow::{Result, anyhow};
use iceoryx2::port::listener::Listener;
use iceoryx2::prelude::ipc;
use icrflow_interfaces::topics::{self, SliceTopic, Topic, TopicId};
use icrflow_interfaces::wire;
use icrflow_runtime::bus::{Bus, BusConfig, Pub, SlicePub, SliceSub, Sub};
use zenoh::Wait;
use zenoh::qos::{CongestionControl, Priority};
use zenoh::sample::Locality;

use crate::carried::{self, Sliced, Visit, Whole};

/// A loop topic's local subscriber, for export: its messages drained as wire bytes.
trait Source {
    /// The listener that wakes the bridge when the topic is published.
    fn listener(&self) -> &Listener<ipc::Service>;
    /// Hands every queued message, as bytes written into the reused `buf`, to `put`;
    /// returns how many.
    fn drain(&self, buf: &mut Vec<u8>, put: &mut dyn FnMut(&[u8])) -> Result<usize>;
}

impl<M: Whole> Source for Sub<M> {
    fn listener(&self) -> &Listener<ipc::Service> {
        Sub::listener(self)
    }

    fn drain(&self, buf: &mut Vec<u8>, put: &mut dyn FnMut(&[u8])) -> Result<usize> {
        let none: &[u8] = &[];
        Ok(Sub::drain(self, |m| {
            wire::encode(m, none, buf);
            put(buf)
        })?)
    }
}

impl<H: Sliced> Source for SliceSub<H, H::Item> {
    fn listener(&self) -> &Listener<ipc::Service> {
        SliceSub::listener(self)
    }

    fn drain(&self, buf: &mut Vec<u8>, put: &mut dyn FnMut(&[u8])) -> Result<usize> {
        Ok(SliceSub::drain(self, |h, items| {
            wire::encode(h, items, buf);
            put(buf)
        })?)
    }
}

/// Opens a topic's [`Source`] on a bus.
struct OpenSource<'a>(&'a Bus);

impl Visit for OpenSource<'_> {
    type Out = Result<Box<dyn Source>>;
    fn whole<M: Whole>(self, topic: Topic<M>) -> Self::Out {
        Ok(Box::new(self.0.subscriber(topic)?))
    }
    fn sliced<H: Sliced>(self, topic: SliceTopic<H, H::Item>) -> Self::Out {
        Ok(Box::new(self.0.slice_subscriber(topic)?))
    }
}

/// A topic published here and read on another host: its local subscriber and Zenoh publisher.
pub struct Export {
    source: Box<dyn Source>,
    publisher: zenoh::pubsub::Publisher<'static>,
}

impl Export {
    /// The export of `topic` (a loop topic) from `bus` through `session`.
    pub fn new(bus: &Bus, session: &zenoh::Session, topic: TopicId) -> Result<Self> {
        let source = carried::visit(topic, OpenSource(bus))
            .ok_or_else(|| anyhow!("no loop topic {topic:?} to carry between hosts"))??;
        let key = topics::link(&bus.config().rig, topic);
        let publisher = session
            .declare_publisher(key.clone())
            .congestion_control(CongestionControl::Block)
            .priority(Priority::RealTime)
            .express(true)
            .wait()
            .map_err(|e| anyhow!("declaring the Zenoh publisher of {key}: {e}"))?;
        Ok(Self { source, publisher })
    }

    /// The listener that wakes the bridge when the topic is published.
    pub fn listener(&self) -> &Listener<ipc::Service> {
        self.source.listener()
    }

    /// Puts every queued message on Zenoh (bytes written into the reused `buf`); returns how
    /// many, or the first failure.
    pub fn forward(&self, buf: &mut Vec<u8>) -> Result<usize> {
        let mut failed = None;
        let publisher = &self.publisher;
        let mut put = |bytes: &[u8]| {
            if let Err(e) = publisher.put(bytes).wait() {
                failed.get_or_insert_with(|| anyhow!("zenoh put on {}: {e}", publisher.key_expr()));
            }
        };
        let n = self.source.drain(buf, &mut put)?;
        failed.map_or(Ok(n), Err)
    }
}

/// A loop topic's local publisher, for import: publishes what the bytes hold, checked.
trait Sink {
    /// Checks `bytes` and publishes the message they hold, unchanged.
    fn import(&mut self, bytes: &[u8]) -> Result<()>;
}

impl<M: Whole> Sink for Pub<M> {
    fn import(&mut self, bytes: &[u8]) -> Result<()> {
        let m: M = wire::decode(bytes, 0, &mut Vec::<u8>::new())?;
        m.header().check(M::KIND)?;
        self.send(m)?;
        Ok(())
    }
}

/// A sliced topic's publisher with the buffer its items are decoded into.
struct SliceSink<H: Sliced> {
    publisher: SlicePub<H, H::Item>,
    items: Vec<H::Item>,
    max: usize,
}

impl<H: Sliced> Sink for SliceSink<H> {
    fn import(&mut self, bytes: &[u8]) -> Result<()> {
        let h: H = wire::decode(bytes, self.max, &mut self.items)?;
        h.header().check(H::KIND)?;
        self.publisher.send(h, &self.items)?;
        Ok(())
    }
}

/// Opens a topic's [`Sink`] on a bus.
struct OpenSink<'a>(&'a Bus);

impl Visit for OpenSink<'_> {
    type Out = Result<Box<dyn Sink>>;
    fn whole<M: Whole>(self, topic: Topic<M>) -> Self::Out {
        Ok(Box::new(self.0.publisher(topic)?))
    }
    fn sliced<H: Sliced>(self, topic: SliceTopic<H, H::Item>) -> Self::Out {
        Ok(Box::new(SliceSink::<H> {
            publisher: self.0.slice_publisher(topic)?,
            items: Vec::with_capacity(topic.max_len),
            max: topic.max_len,
        }))
    }
}

/// The sink of `topic` on `bus`.
fn sink(bus: &Bus, topic: TopicId) -> Result<Box<dyn Sink>> {
    carried::visit(topic, OpenSink(bus))
        .ok_or_else(|| anyhow!("no loop topic {topic:?} to carry between hosts"))?
}

/// How long the import thread waits for a message before it checks whether to stop.
const POLL_STOP: Duration = Duration::from_millis(100);

/// The thread that takes the loop topics other hosts publish and publishes them locally.
pub struct Importer {
    stop: Arc<AtomicBool>,
    thread: Option<std::thread::JoinHandle<Result<()>>>,
    /// Messages published locally.
    pub imported: Arc<AtomicU64>,
    /// Why messages were refused (one entry per refusal).
    pub refusals: mpsc::Receiver<String>,
}

impl Importer {
    /// Starts importing `imports` (loop topics) from Zenoh into the bus of `config`.
    pub fn start(
        session: &zenoh::Session,
        config: &BusConfig,
        imports: &[TopicId],
    ) -> Result<Self> {
        let rig = config.rig.clone();
        let keys = format!("{}*", topics::link_prefix(&rig));
        let subscriber = session
            .declare_subscriber(&keys)
            .allowed_origin(Locality::Remote)
            .wait()
            .map_err(|e| anyhow!("declaring the Zenoh subscriber of {keys}: {e}"))?;
        let stop = Arc::new(AtomicBool::new(false));
        let imported = Arc::new(AtomicU64::new(0));
        let (tell, refusals) = mpsc::channel();
        let config = config.clone();
        let imports = imports.to_vec();
        let (stopping, count) = (stop.clone(), imported.clone());
        // The ports are made on the thread that uses them (iceoryx2 ports stay on theirs).
        let (ready_tx, ready_rx) = mpsc::channel();
        let thread = std::thread::Builder::new()
            .name("link-in".into())
            .spawn(move || -> Result<()> {
                let setup = || -> Result<_> {
                    let bus = Bus::new("bridge-link", &config)?;
                    let mut sinks = Vec::new();
                    for &t in &imports {
                        sinks.push((topics::link(&rig, t), sink(&bus, t)?));
                    }
                    Ok((bus, sinks))
                };
                let (_bus, mut sinks) = match setup() {
                    Ok(s) => {
                        let _ = ready_tx.send(Ok(()));
                        s
                    }
                    Err(e) => {
                        let _ = ready_tx.send(Err(e));
                        return Ok(());
                    }
                };
                let mut said = std::collections::BTreeSet::new();
                while !stopping.load(Ordering::Relaxed) {
                    let sample = match subscriber.recv_timeout(POLL_STOP) {
                        Ok(Some(sample)) => sample,
                        Ok(None) => continue,
                        Err(e) => return Err(anyhow!("the Zenoh subscriber of {keys}: {e}")),
                    };
                    let key = sample.key_expr().as_str();
                    let result = match sinks.iter_mut().find(|(k, _)| k == key) {
                        Some((_, sink)) => sink.import(&sample.payload().to_bytes()),
                        None => Err(anyhow!("this host does not take that topic from others")),
                    };
                    match result {
                        Ok(()) => {
                            count.fetch_add(1, Ordering::Relaxed);
                        }
                        Err(e) => {
                            let why = format!("{e:#}");
                            // Said once per key and reason (at most a hundred), counted always.
                            if said.len() < 100 && said.insert((key.to_string(), why.clone())) {
                                eprintln!("icrflow-bridge: refused a message on {key}: {why}");
                            }
                            let _ = tell.send(format!("{key}: {why}"));
                        }
                    }
                }
                Ok(())
            })
            .map_err(|e| anyhow!("starting the link import thread: {e}"))?;
        ready_rx
            .recv()
            .map_err(|_| anyhow!("the link import thread ended while starting"))??;
        Ok(Self {
            stop,
            thread: Some(thread),
            imported,
            refusals,
        })
    }

    /// Whether the thread has ended (its subscriber failed).
    pub fn ended(&self) -> bool {
        self.thread.as_ref().is_none_or(|t| t.is_finished())
    }

    /// Stops the thread and returns its error, if it failed.
    pub fn stop(mut self) -> Result<()> {
        self.stop.store(true, Ordering::Relaxed);
        match self.thread.take() {
            Some(t) => t
                .join()
                .map_err(|_| anyhow!("the link import thread panicked"))?,
            None => Ok(()),
        }
    }
}
