//! The local bus: iceoryx2 publish-subscribe topics, each paired with an event service of the
//! same name so that a receiving node sleeps on the event's listener until a sender notifies
//! it (no busy polling; [`crate::event::serve`] waits on the listeners' file descriptors).
//!
//! Isolation: every run uses its own iceoryx2 *prefix* (the name prefix of its shared-memory
//! objects) and *root* directory (its service, node and socket files), so two runs, or a test
//! beside a real run, never see each other ([`BusConfig`]). Topic services are
//! `icrflow/<rig>/<topic>`.

use std::fmt::Debug;
use std::path::PathBuf;

use iceoryx2::port::listener::Listener;
use iceoryx2::port::notifier::Notifier;
use iceoryx2::port::publisher::Publisher;
use iceoryx2::port::subscriber::Subscriber;
use iceoryx2::prelude::*;
use iceoryx2::service::builder::publish_subscribe::{
    PublishSubscribeOpenError, PublishSubscribeOpenOrCreateError,
};
use icrflow_interfaces::Message;
use icrflow_interfaces::topics::{self, SliceTopic, Topic};

/// Messages a subscriber keeps queued (the oldest is overwritten beyond that).
const BUFFER: usize = 32;

/// Why the bus failed, with the topic or node named.
#[derive(Debug, thiserror::Error)]
#[non_exhaustive]
pub enum BusError {
    /// The run's settings are unusable.
    #[error("bus settings: {0}")]
    Settings(String),
    /// The iceoryx2 node could not be created.
    #[error("cannot create iceoryx2 node {name:?}: {reason}")]
    Node {
        /// Node name.
        name: String,
        /// iceoryx2's reason.
        reason: String,
    },
    /// The topic exists with another message type, user header or schema version.
    #[error(
        "topic {topic} carries another message type or schema version than this node's {expected}: refusing to connect"
    )]
    Mismatch {
        /// The service name.
        topic: String,
        /// This node's type name.
        expected: String,
    },
    /// Another failure on a topic.
    #[error("topic {topic}: {reason}")]
    Topic {
        /// The service name.
        topic: String,
        /// What failed.
        reason: String,
    },
}

/// Where a run's iceoryx2 resources live (handed to a node in its
/// [`Launch`](crate::launch::Launch)).
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct BusConfig {
    /// Rig name (part of every topic name).
    pub rig: String,
    /// iceoryx2 prefix of the run's shared-memory objects.
    pub prefix: String,
    /// iceoryx2 root directory of the run's files.
    pub root: PathBuf,
}

impl BusConfig {
    /// A configuration; the prefix must be a short file-name-safe string and the root an
    /// absolute directory.
    pub fn new(rig: &str, prefix: &str, root: PathBuf) -> Result<Self, BusError> {
        let safe = |s: &str| {
            !s.is_empty()
                && s.len() <= 48
                && s.bytes()
                    .all(|b| b.is_ascii_alphanumeric() || b == b'_' || b == b'-')
        };
        if !safe(rig) {
            return Err(BusError::Settings(format!(
                "rig name {rig:?}: use 1 to 48 letters, digits, '_' or '-'"
            )));
        }
        if !safe(prefix) {
            return Err(BusError::Settings(format!(
                "iceoryx2 prefix {prefix:?}: use 1 to 48 letters, digits, '_' or '-'"
            )));
        }
        if !root.is_absolute() {
            return Err(BusError::Settings(format!(
                "iceoryx2 root {} must be an absolute path",
                root.display()
            )));
        }
        Ok(Self {
            rig: rig.into(),
            prefix: prefix.into(),
            root,
        })
    }

    /// The iceoryx2 configuration: this run's prefix and root, defaults otherwise.
    pub fn iceoryx(&self) -> Result<Config, BusError> {
        let mut c = Config::default();
        c.global.prefix = FileName::new(self.prefix.as_bytes())
            .map_err(|e| BusError::Settings(format!("prefix {:?}: {e:?}", self.prefix)))?;
        let mut root = self.root.display().to_string();
        if !root.ends_with('/') {
            root.push('/');
        }
        let path = Path::new(root.as_bytes())
            .map_err(|e| BusError::Settings(format!("root {root:?}: {e:?}")))?;
        c.global.set_root_path(&path);
        Ok(c)
    }

    /// The service name of `topic` on this rig.
    pub fn service(&self, topic: &str) -> String {
        topics::service(&self.rig, topic)
    }

    /// A bus of the calling process alone, for tests and benchmarks: rig `test`, a prefix and
    /// a root under `/tmp` named by `tag` and the process id.
    pub fn isolated(tag: &str) -> Result<Self, BusError> {
        let id = std::process::id();
        Self::new(
            "test",
            &format!("icrt_{tag}_{id}_"),
            PathBuf::from(format!("/tmp/icrflow-test-{tag}-{id}")),
        )
    }

    /// The run's files left in `/dev/shm` (but the one global counter iceoryx2 keeps by
    /// design) and under its root.
    pub fn leftovers(&self) -> Vec<String> {
        fn walk(p: &std::path::Path, out: &mut Vec<String>) {
            for e in std::fs::read_dir(p).into_iter().flatten().flatten() {
                let path = e.path();
                if path.is_dir() {
                    walk(&path, out);
                } else {
                    out.push(path.display().to_string());
                }
            }
        }
        let mut out: Vec<String> = self
            .shared_memory()
            .into_iter()
            .filter(|p| !p.to_string_lossy().ends_with("global_mgmt"))
            .map(|p| p.display().to_string())
            .collect();
        walk(&self.root, &mut out);
        out
    }

    /// Removes what iceoryx2 leaves of a finished run: its root directory and its
    /// shared-memory objects (the one counter it keeps by design included). Best effort: what
    /// cannot be removed stays, for [`BusConfig::leftovers`] to show.
    pub fn remove_files(&self) {
        let _ = std::fs::remove_dir_all(&self.root);
        for path in self.shared_memory() {
            let _ = std::fs::remove_file(path);
        }
    }

    /// The run's objects in `/dev/shm`.
    fn shared_memory(&self) -> Vec<PathBuf> {
        std::fs::read_dir("/dev/shm")
            .into_iter()
            .flatten()
            .flatten()
            .filter(|e| e.file_name().to_string_lossy().starts_with(&self.prefix))
            .map(|e| e.path())
            .collect()
    }
}

/// A node's connection to the bus.
pub struct Bus {
    node: Node<ipc::Service>,
    config: BusConfig,
}

/// A publisher with the notifier that wakes the topic's subscribers.
pub struct Pub<T: Debug + ZeroCopySend + 'static> {
    publisher: Publisher<ipc::Service, T, ()>,
    notifier: Notifier<ipc::Service>,
    topic: String,
}

/// A publisher of a fixed user header plus a dynamic slice (for large payloads).
pub struct SlicePub<
    H: Debug + ZeroCopySend + Default + 'static,
    T: Debug + ZeroCopySend + Copy + 'static,
> {
    publisher: Publisher<ipc::Service, [T], H>,
    notifier: Notifier<ipc::Service>,
    topic: String,
}

/// A subscriber of a user header plus a dynamic slice.
pub struct SliceSub<
    H: Debug + ZeroCopySend + Copy + 'static,
    T: Debug + ZeroCopySend + Copy + 'static,
> {
    subscriber: Subscriber<ipc::Service, [T], H>,
    listener: Listener<ipc::Service>,
    topic: String,
}

/// A subscriber with the listener its node sleeps on.
pub struct Sub<T: Debug + ZeroCopySend + 'static> {
    subscriber: Subscriber<ipc::Service, T, ()>,
    listener: Listener<ipc::Service>,
    topic: String,
}

fn open_error(topic: &str, expected: &str, e: PublishSubscribeOpenOrCreateError) -> BusError {
    match e {
        PublishSubscribeOpenOrCreateError::PublishSubscribeOpenError(
            PublishSubscribeOpenError::IncompatibleTypes,
        ) => BusError::Mismatch {
            topic: topic.into(),
            expected: expected.into(),
        },
        other => BusError::Topic {
            topic: topic.into(),
            reason: format!("{other:?}"),
        },
    }
}

fn topic_error(topic: &str, what: &str, e: impl Debug) -> BusError {
    BusError::Topic {
        topic: topic.into(),
        reason: format!("{what}: {e:?}"),
    }
}

/// Sets iceoryx2's logging for one of our processes: its warnings and errors on stderr, not
/// its notes. And iceoryx2's process-wide default configuration is loaded now, with its
/// logging off: our nodes are made with the run's own configuration ([`BusConfig::iceoryx`]),
/// but iceoryx2 falls back on the process-wide one where none is given (the resources of a
/// dead node whose details could not be read, which [`crate::supervise::cleanup_dead_nodes`]
/// removes), and loading it warns "No config file was loaded, a config with default values
/// will be used" on stderr where no iceoryx2 config file exists: library noise in a run's
/// messages. Loaded now, it is what iceoryx2 would load then (a config file if there is one,
/// else the defaults), said nowhere.
pub fn set_up_logging() {
    set_log_level(LogLevel::Fatal);
    let _ = Config::global_config();
    set_log_level(LogLevel::Warn);
}

impl Bus {
    /// Creates this process's iceoryx2 node `name` on the run's bus.
    pub fn new(name: &str, config: &BusConfig) -> Result<Self, BusError> {
        let node_error = |reason: String| BusError::Node {
            name: name.into(),
            reason,
        };
        let node_name: NodeName = name
            .try_into()
            .map_err(|e| node_error(format!("bad name: {e:?}")))?;
        let node = NodeBuilder::new()
            .name(&node_name)
            .config(&config.iceoryx()?)
            .create::<ipc::Service>()
            .map_err(|e| node_error(format!("{e:?}")))?;
        Ok(Self {
            node,
            config: config.clone(),
        })
    }

    /// The iceoryx2 node.
    pub fn node(&self) -> &Node<ipc::Service> {
        &self.node
    }

    /// The bus configuration.
    pub fn config(&self) -> &BusConfig {
        &self.config
    }

    fn event(
        &self,
        topic: &str,
    ) -> Result<iceoryx2::service::port_factory::event::PortFactory<ipc::Service>, BusError> {
        let name: ServiceName = topic
            .try_into()
            .map_err(|e| topic_error(topic, "bad name", e))?;
        self.node
            .service_builder(&name)
            .event()
            .max_notifiers(8)
            .max_listeners(16)
            .open_or_create()
            .map_err(|e| topic_error(topic, "event service", e))
    }

    /// The notifier that wakes `topic`'s subscribers.
    fn notifier(&self, topic: &str) -> Result<Notifier<ipc::Service>, BusError> {
        self.event(topic)?
            .notifier_builder()
            .create()
            .map_err(|e| topic_error(topic, "notifier", e))
    }

    /// The listener a subscriber of `topic` waits on.
    fn listener(&self, topic: &str) -> Result<Listener<ipc::Service>, BusError> {
        self.event(topic)?
            .listener_builder()
            .create()
            .map_err(|e| topic_error(topic, "listener", e))
    }

    fn pubsub<T: Debug + ZeroCopySend + 'static>(
        &self,
        topic: &str,
    ) -> Result<
        iceoryx2::service::port_factory::publish_subscribe::PortFactory<ipc::Service, T, ()>,
        BusError,
    > {
        let name: ServiceName = topic
            .try_into()
            .map_err(|e| topic_error(topic, "bad name", e))?;
        let expected = icrflow_interfaces::type_name::<T>();
        self.node
            .service_builder(&name)
            .publish_subscribe::<T>()
            .history_size(1)
            .subscriber_max_buffer_size(BUFFER)
            .max_publishers(16)
            .max_subscribers(16)
            .max_nodes(32)
            .open_or_create()
            .map_err(|e| open_error(topic, expected, e))
    }

    /// A publisher on `topic`.
    pub fn publisher<T: Debug + ZeroCopySend + 'static>(
        &self,
        topic: Topic<T>,
    ) -> Result<Pub<T>, BusError> {
        self.publisher_named(topic.name())
    }

    /// A publisher of `T` on a topic outside the pipeline's (a benchmark's, a test's), named
    /// `topic`: the caller answers for the type (a topic opened with another is refused).
    pub fn publisher_named<T: Debug + ZeroCopySend + 'static>(
        &self,
        topic: &str,
    ) -> Result<Pub<T>, BusError> {
        let full = self.config.service(topic);
        let publisher = self
            .pubsub::<T>(&full)?
            .publisher_builder()
            .create()
            .map_err(|e| topic_error(&full, "publisher", e))?;
        let notifier = self.notifier(&full)?;
        Ok(Pub {
            publisher,
            notifier,
            topic: full,
        })
    }

    fn slice_service<H: Debug + ZeroCopySend + 'static, T: Debug + ZeroCopySend + 'static>(
        &self,
        topic: &str,
    ) -> Result<
        iceoryx2::service::port_factory::publish_subscribe::PortFactory<ipc::Service, [T], H>,
        BusError,
    > {
        let name: ServiceName = topic
            .try_into()
            .map_err(|e| topic_error(topic, "bad name", e))?;
        let expected = format!(
            "{} + [{}]",
            icrflow_interfaces::type_name::<H>(),
            icrflow_interfaces::type_name::<T>()
        );
        self.node
            .service_builder(&name)
            .publish_subscribe::<[T]>()
            .user_header::<H>()
            .history_size(1)
            .subscriber_max_buffer_size(BUFFER)
            .max_publishers(16)
            .max_subscribers(16)
            .max_nodes(32)
            .open_or_create()
            .map_err(|e| open_error(topic, &expected, e))
    }

    /// A publisher of header `H` plus up to the topic's `max_len` items `T` (more are
    /// refused) on `topic`.
    pub fn slice_publisher<
        H: Debug + ZeroCopySend + Default + 'static,
        T: Debug + ZeroCopySend + Copy + 'static,
    >(
        &self,
        topic: SliceTopic<H, T>,
    ) -> Result<SlicePub<H, T>, BusError> {
        let max_len = topic.max_len;
        let full = self.config.service(topic.name());
        let publisher = self
            .slice_service::<H, T>(&full)?
            .publisher_builder()
            .initial_max_slice_len(max_len.max(1))
            .create()
            .map_err(|e| topic_error(&full, "publisher", e))?;
        let notifier = self.notifier(&full)?;
        Ok(SlicePub {
            publisher,
            notifier,
            topic: full,
        })
    }

    /// A subscriber of header `H` plus items `T` on `topic`.
    pub fn slice_subscriber<
        H: Debug + ZeroCopySend + Copy + 'static,
        T: Debug + ZeroCopySend + Copy + 'static,
    >(
        &self,
        topic: SliceTopic<H, T>,
    ) -> Result<SliceSub<H, T>, BusError> {
        let full = self.config.service(topic.name());
        let subscriber = self
            .slice_service::<H, T>(&full)?
            .subscriber_builder()
            .buffer_size(BUFFER)
            .create()
            .map_err(|e| topic_error(&full, "subscriber", e))?;
        let listener = self.listener(&full)?;
        Ok(SliceSub {
            subscriber,
            listener,
            topic: full,
        })
    }

    /// A subscriber on `topic`.
    pub fn subscriber<T: Debug + ZeroCopySend + 'static>(
        &self,
        topic: Topic<T>,
    ) -> Result<Sub<T>, BusError> {
        self.subscriber_named(topic.name())
    }

    /// A subscriber of `T` on a topic outside the pipeline's, named `topic` (see
    /// [`Bus::publisher_named`]).
    pub fn subscriber_named<T: Debug + ZeroCopySend + 'static>(
        &self,
        topic: &str,
    ) -> Result<Sub<T>, BusError> {
        let full = self.config.service(topic);
        let subscriber = self
            .pubsub::<T>(&full)?
            .subscriber_builder()
            .buffer_size(BUFFER)
            .create()
            .map_err(|e| topic_error(&full, "subscriber", e))?;
        let listener = self.listener(&full)?;
        Ok(Sub {
            subscriber,
            listener,
            topic: full,
        })
    }
}

impl<T: Debug + ZeroCopySend + 'static> Pub<T> {
    /// Writes `value` into a loaned sample, sends it and wakes the subscribers. Returns the
    /// number of subscribers that received it.
    pub fn send(&self, value: T) -> Result<usize, BusError> {
        let sample = self
            .publisher
            .loan_uninit()
            .map_err(|e| topic_error(&self.topic, "loan", e))?;
        let receivers = sample
            .write_payload(value)
            .send()
            .map_err(|e| topic_error(&self.topic, "send", e))?;
        self.notifier
            .notify()
            .map_err(|e| topic_error(&self.topic, "notify", e))?;
        Ok(receivers)
    }

    /// The service name.
    pub fn topic(&self) -> &str {
        &self.topic
    }
}

impl<T: Debug + ZeroCopySend + Message + 'static> Pub<T> {
    /// Stamps the message's header as published now ([`Header::stamp`]) and sends it.
    ///
    /// [`Header::stamp`]: icrflow_interfaces::Header::stamp
    pub fn publish(&self, mut message: T) -> Result<usize, BusError> {
        message.header_mut().stamp();
        self.send(message)
    }
}

impl<T: Debug + ZeroCopySend + Copy + 'static> Sub<T> {
    /// The listener its node sleeps on ([`crate::event::serve`]).
    pub fn listener(&self) -> &Listener<ipc::Service> {
        &self.listener
    }

    /// Consumes the pending wake-ups and calls `f` on every queued message, oldest first.
    pub fn drain(&self, mut f: impl FnMut(&T)) -> Result<usize, BusError> {
        self.listener
            .try_wait(|_| {})
            .map_err(|e| topic_error(&self.topic, "listener", e))?;
        let mut n = 0;
        while let Some(sample) = self
            .subscriber
            .receive()
            .map_err(|e| topic_error(&self.topic, "receive", e))?
        {
            f(sample.payload());
            n += 1;
        }
        Ok(n)
    }

    /// The newest queued message, if any (older ones are dropped), consuming wake-ups.
    pub fn latest(&self) -> Result<Option<T>, BusError> {
        let mut last = None;
        self.drain(|m| last = Some(*m))?;
        Ok(last)
    }

    /// The service name.
    pub fn topic(&self) -> &str {
        &self.topic
    }
}

impl<H: Debug + ZeroCopySend + Default + 'static, T: Debug + ZeroCopySend + Copy + 'static>
    SlicePub<H, T>
{
    /// Sends `header` and a copy of `items` in one loaned sample and wakes the subscribers.
    pub fn send(&self, header: H, items: &[T]) -> Result<usize, BusError> {
        let mut sample = self
            .publisher
            .loan_slice_uninit(items.len())
            .map_err(|e| topic_error(&self.topic, "loan", e))?;
        *sample.user_header_mut() = header;
        let receivers = sample
            .write_from_slice(items)
            .send()
            .map_err(|e| topic_error(&self.topic, "send", e))?;
        self.notifier
            .notify()
            .map_err(|e| topic_error(&self.topic, "notify", e))?;
        Ok(receivers)
    }
}

impl<
    H: Debug + ZeroCopySend + Default + Message + 'static,
    T: Debug + ZeroCopySend + Copy + 'static,
> SlicePub<H, T>
{
    /// Stamps the header as published now and sends it with `items` ([`Pub::publish`]).
    pub fn publish(&self, mut header: H, items: &[T]) -> Result<usize, BusError> {
        header.header_mut().stamp();
        self.send(header, items)
    }
}

impl<H: Debug + ZeroCopySend + Copy + 'static, T: Debug + ZeroCopySend + Copy + 'static>
    SliceSub<H, T>
{
    /// The listener its node sleeps on ([`crate::event::serve`]).
    pub fn listener(&self) -> &Listener<ipc::Service> {
        &self.listener
    }

    /// Consumes the pending wake-ups and calls `f` on every queued message (header and
    /// items), oldest first.
    pub fn drain(&self, mut f: impl FnMut(&H, &[T])) -> Result<usize, BusError> {
        self.listener
            .try_wait(|_| {})
            .map_err(|e| topic_error(&self.topic, "listener", e))?;
        let mut n = 0;
        while let Some(sample) = self
            .subscriber
            .receive()
            .map_err(|e| topic_error(&self.topic, "receive", e))?
        {
            f(sample.user_header(), sample.payload());
            n += 1;
        }
        Ok(n)
    }

    /// The newest queued message, if any: its header, with its items copied into `items`
    /// (cleared first; its capacity is reused). Consumes wake-ups and older messages.
    pub fn latest(&self, items: &mut Vec<T>) -> Result<Option<H>, BusError> {
        let mut header = None;
        self.drain(|h, payload| {
            header = Some(*h);
            items.clear();
            items.extend_from_slice(payload);
        })?;
        Ok(header)
    }
}
