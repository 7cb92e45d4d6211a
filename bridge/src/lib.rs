//! The Zenoh side of the pipeline: the bridge node (`icrflow-bridge`), which publishes the
//! run's local iceoryx2 topics on Zenoh as JSON for monitoring from this or another machine,
//! and the Zenoh session settings shared with `icrflow monitor`.
//!
//! Why not iceoryx2's own tunnel: the Zenoh backend of the iceoryx2 tunnel
//! (`iceoryx2-tunnel-zenoh`) is released up to 0.8.1, built against iceoryx2 0.8, and iceoryx2
//! refuses to connect processes of different versions; we use 0.10. It would also carry our
//! `#[repr(C)]` messages as raw bytes, which only a client with our layouts can read, while
//! monitoring needs a payload any Zenoh client can decode (JSON, [`json`]), and it tunnels
//! every service both ways, where the pipeline must choose per topic and direction.
//!
//! The bridge is off the control loop: it polls its subscribers every
//! [`icrflow_runtime::event::RESYNC`] (no publisher on the loop wakes it), and publishes with
//! congestion control `Drop` at a low priority, so a slow or lost link drops monitoring
//! messages instead of stalling anything local.
//!
//! Remote peers only read: with `zenoh.read_only` (the default) the session's access control
//! ([`read_only_acl`]) lets them subscribe, on any key expression, and receive what the
//! bridge puts on the rig's key expressions, and nothing else. The bridge takes no input from
//! Zenoh on the monitoring keys; whatever remote message reaches it there (read-only off) is
//! checked ([`json::envelope`]), logged with the reason, counted as refused, and dropped.

#![warn(missing_docs)]

mod carried;
pub mod json;
pub mod link;

/// The Zenoh crate, as this crate uses it (for `icrflow monitor`).
pub use zenoh;

use anyhow::{Context as _, Result, anyhow};
use icrflow_interfaces::topics::{self, SliceTopic, Topic, TopicId};
use icrflow_runtime::bus::{SliceSub, Sub};
use icrflow_runtime::event::serve;
use icrflow_runtime::health::Health;
use icrflow_runtime::node::Context;
use icrflow_scenario::Config;
use icrflow_scenario::ZenohSpec;
use zenoh::Wait;
use zenoh::qos::{CongestionControl, Priority};
use zenoh::sample::Locality;

use crate::carried::{Sliced, Visit, Whole};

/// The access control of a read-only pipeline session on rig `rig`: every remote peer may
/// declare a subscriber on any key expression and receives what the session publishes on the
/// rig's key expressions, and nothing else; the loop topics in `imports` (a split pipeline's
/// topics this host takes from the others) may be put by the peers logged in as one of
/// `link_users` (by any peer when that is empty); everything else a remote peer sends (a put,
/// a delete, a query, a queryable, a liveliness token, on any key) is denied by default.
///
/// Why subscriber declarations are allowed on `**`, not on the rig's `icrflow/<rig>/**`:
/// Zenoh 1.10's access control allows a declaration only when an allowing rule's key
/// expression *includes* the declared one (`nodes_including` in its policy decision point),
/// so a rule on `icrflow/<rig>/**` silently drops a subscriber on `icrflow/**` or `**`, a
/// superset, and such a client gets an empty stream. A subscription carries no data into the
/// session; what reaches the subscriber is decided by the egress rule on the puts
/// (`monitoring-out`: only the rig's keys), so allowing every declaration lets any client
/// read the rig's keys, whatever its key expression, and write nothing.
pub fn read_only_acl(rig: &str, imports: &[TopicId], link_users: &[String]) -> serde_json::Value {
    let keys = [topics::service(rig, "**")];
    let mut rules = vec![
        serde_json::json!({
            "id": "monitoring-out",
            "messages": ["put"],
            "flows": ["egress"],
            "permission": "allow",
            "key_exprs": keys,
        }),
        serde_json::json!({
            "id": "remote-subscribe",
            "messages": ["declare_subscriber"],
            "flows": ["ingress"],
            "permission": "allow",
            "key_exprs": ["**"],
        }),
        serde_json::json!({
            "id": "bridge-subscribe",
            "messages": ["declare_subscriber"],
            "flows": ["egress"],
            "permission": "allow",
            "key_exprs": keys,
        }),
    ];
    let mut subjects = vec![serde_json::json!({ "id": "every-peer" })];
    let mut policies = vec![serde_json::json!({
        "rules": ["monitoring-out", "remote-subscribe", "bridge-subscribe"],
        "subjects": ["every-peer"],
    })];
    if !imports.is_empty() {
        let links: Vec<String> = imports.iter().map(|&t| topics::link(rig, t)).collect();
        rules.push(serde_json::json!({
            "id": "link-in",
            "messages": ["put"],
            "flows": ["ingress"],
            "permission": "allow",
            "key_exprs": links,
        }));
        let subject = if link_users.is_empty() {
            "every-peer"
        } else {
            subjects.push(serde_json::json!({ "id": "link-peers", "usernames": link_users }));
            "link-peers"
        };
        policies.push(serde_json::json!({ "rules": ["link-in"], "subjects": [subject] }));
    }
    serde_json::json!({
        "enabled": true,
        "default_permission": "deny",
        "rules": rules,
        "subjects": subjects,
        "policies": policies,
    })
}

/// A Zenoh session's settings from the config's `[zenoh]` section, for rig `rig` on a host
/// that takes the loop topics `imports` from other hosts.
pub fn session_config(z: &ZenohSpec, rig: &str, imports: &[TopicId]) -> Result<zenoh::Config> {
    let mut c = zenoh::Config::default();
    let mut set = |key: &str, value: serde_json::Value| -> Result<()> {
        c.insert_json5(key, &value.to_string())
            .map_err(|e| anyhow!("Zenoh refused the setting {key} = {value}: {}", words(&e)))
    };
    set("mode", serde_json::json!(z.mode))?;
    set("listen/endpoints", serde_json::json!(z.listen))?;
    set("connect/endpoints", serde_json::json!(z.connect))?;
    set("scouting/multicast/enabled", serde_json::json!(z.scouting))?;
    if z.read_only {
        set("access_control", read_only_acl(rig, imports, &z.link_users))?;
    }
    if let Some(user) = &z.user {
        let password = std::env::var(icrflow_scenario::PASSWORD_ENV).map_err(|_| {
            anyhow!(
                "zenoh.user {user:?}: its password is read from {}, which is not set",
                icrflow_scenario::PASSWORD_ENV
            )
        })?;
        set("transport/auth/usrpwd/user", serde_json::json!(user))?;
        set(
            "transport/auth/usrpwd/password",
            serde_json::json!(password),
        )?;
    }
    if let Some(file) = &z.users_file {
        set(
            "transport/auth/usrpwd/dictionary_file",
            serde_json::json!(file.display().to_string()),
        )?;
    }
    Ok(c)
}

/// The settings of a client session that connects to `endpoint` only (`icrflow monitor`),
/// authenticating as `user` with `password` if given.
pub fn client_config(endpoint: &str, login: Option<(&str, &str)>) -> Result<zenoh::Config> {
    let mut c = session_config(
        &ZenohSpec {
            enabled: true,
            mode: "client".into(),
            listen: Vec::new(),
            connect: vec![endpoint.into()],
            scouting: false,
            read_only: false,
            users_file: None,
            link_users: Vec::new(),
            user: None,
            monitor: Vec::new(),
        },
        "",
        &[],
    )?;
    if let Some((user, password)) = login {
        for (key, value) in [("user", user), ("password", password)] {
            c.insert_json5(
                &format!("transport/auth/usrpwd/{key}"),
                &serde_json::json!(value).to_string(),
            )
            .map_err(|e| {
                anyhow!(
                    "Zenoh refused the setting transport/auth/usrpwd/{key}: {}",
                    words(&e)
                )
            })?;
        }
    }
    Ok(c)
}

/// Opens a Zenoh session, naming the endpoints (`what`) when that fails, in our words.
pub fn open(config: zenoh::Config, what: &str) -> Result<zenoh::Session> {
    zenoh::open(config)
        .wait()
        .map_err(|e| anyhow!("cannot open the Zenoh session ({what}): {}", words(&e)))
}

/// A Zenoh error's message as a user reads it: its text without the source location Zenoh
/// appends (` at /root/.cargo/registry/.../orchestrator.rs:447.`), and, for a configuration
/// value Zenoh could not parse (`Json5Err(Message { msg: "...", location: ... })`), the
/// message alone.
pub fn words(e: &dyn std::fmt::Display) -> String {
    let text = e.to_string();
    let text = match text.find("msg: \"") {
        Some(i) => {
            let rest = &text[i + 6..];
            rest.find('"').map_or(rest, |end| &rest[..end]).to_string()
        }
        None => text,
    };
    let cut = text
        .find(" at /")
        .or_else(|| text.find(" at src/"))
        .unwrap_or(text.len());
    // Zenoh's debug form of an endpoint list: `[Single(tcp/127.0.0.1:7447)]`.
    text[..cut]
        .trim()
        .trim_end_matches(['.', '!'])
        .trim()
        .replace("[Single(", "[")
        .replace(")]", "]")
}

/// A monitored topic's local subscriber: its messages drained as monitoring JSON.
trait Monitored {
    /// Hands every queued message's JSON (written into the reused `text`), or why it has
    /// none, to `put`; returns how many.
    fn drain(
        &self,
        rig: &str,
        text: &mut Vec<u8>,
        put: &mut dyn FnMut(Result<&[u8]>),
    ) -> Result<usize>;
}

impl<M: Whole> Monitored for Sub<M> {
    fn drain(
        &self,
        rig: &str,
        text: &mut Vec<u8>,
        put: &mut dyn FnMut(Result<&[u8]>),
    ) -> Result<usize> {
        Ok(Sub::drain(self, |m| {
            put(m.write_json(rig, text).map(|()| text.as_slice()))
        })?)
    }
}

impl<H: Sliced> Monitored for SliceSub<H, H::Item> {
    fn drain(
        &self,
        rig: &str,
        text: &mut Vec<u8>,
        put: &mut dyn FnMut(Result<&[u8]>),
    ) -> Result<usize> {
        Ok(SliceSub::drain(self, |h, items| {
            put(h.write_json(items, rig, text).map(|()| text.as_slice()))
        })?)
    }
}

/// Opens a monitored topic's subscriber on a bus.
struct OpenMonitored<'a>(&'a icrflow_runtime::bus::Bus);

impl Visit for OpenMonitored<'_> {
    type Out = Result<Box<dyn Monitored>>;
    fn whole<M: Whole>(self, topic: Topic<M>) -> Self::Out {
        if !M::MONITORED {
            anyhow::bail!("zenoh.monitor: topic {:?} is not monitored", topic.name());
        }
        Ok(Box::new(self.0.subscriber(topic)?))
    }
    fn sliced<H: Sliced>(self, topic: SliceTopic<H, H::Item>) -> Self::Out {
        Ok(Box::new(self.0.slice_subscriber(topic)?))
    }
}

/// Runs the bridge node.
pub fn run(ctx: &Context<Config>) -> Result<()> {
    let z = &ctx.scenario.zenoh;
    let rig = ctx.scenario.pipeline.rig.as_str();
    let links = topics::links(&ctx.scenario.pipeline.nodes);
    let session = open(
        session_config(z, rig, &links.import)?,
        &format!("listen {:?}, connect {:?}", z.listen, z.connect),
    )?;
    // A split pipeline's loop topics: out as soon as they are published here, in on a thread.
    let exports = links
        .export
        .iter()
        .map(|&t| link::Export::new(&ctx.bus, &session, t))
        .collect::<Result<Vec<_>>>()?;
    let importer = if links.import.is_empty() {
        None
    } else {
        Some(link::Importer::start(
            &session,
            ctx.bus.config(),
            &links.import,
        )?)
    };
    if !links.export.is_empty() || !links.import.is_empty() {
        eprintln!(
            "icrflow-bridge: this host runs {:?}; to other hosts: {:?}; from them: {:?}",
            ctx.scenario.pipeline.nodes, links.export, links.import
        );
    }
    let mut forwards = Vec::with_capacity(z.monitor.len());
    for topic in &z.monitor {
        let forward = TopicId::from_name(topic)
            .and_then(|id| carried::visit(id, OpenMonitored(&ctx.bus)))
            .ok_or_else(|| anyhow!("zenoh.monitor: no such topic {topic:?}"))??;
        let publisher = session
            .declare_publisher(topics::service(rig, topic))
            .congestion_control(CongestionControl::Drop)
            .priority(Priority::DataLow)
            .wait()
            .map_err(|e| anyhow!("declaring the Zenoh publisher of {topic}: {e}"))?;
        forwards.push((forward, publisher));
    }
    // Whatever a remote peer puts on the rig's monitoring key expressions. Read-only (the
    // default), the access control drops it before it gets here; otherwise it is checked and
    // ignored: the bridge takes no input there (the loop topics come in on `link/`).
    let inbound_keys = topics::service(rig, "*");
    let inbound = session
        .declare_subscriber(&inbound_keys)
        .allowed_origin(Locality::Remote)
        .wait()
        .map_err(|e| anyhow!("declaring the Zenoh subscriber of {inbound_keys}: {e}"))?;
    let mut said = std::collections::BTreeSet::new();
    let mut health = Health::new(ctx)?;
    let mut text: Vec<u8> = Vec::with_capacity(4096);
    let mut bytes: Vec<u8> = Vec::with_capacity(1 << 16);
    let mut imported = 0;
    let wake: Vec<_> = exports.iter().map(|e| e.listener()).collect();
    let served = serve(ctx, &wake, None, |_| {
        for export in &exports {
            // A blocked link blocks here (congestion control `Block`), never the nodes.
            match export.forward(&mut bytes) {
                Ok(n) => health.processed += n as u64,
                Err(e) => health.refuse(format!("{e:#}")),
            }
        }
        if let Some(importer) = &importer {
            let n = importer.imported.load(std::sync::atomic::Ordering::Relaxed);
            health.processed += n - imported;
            imported = n;
            while let Ok(why) = importer.refusals.try_recv() {
                health.refuse(why);
            }
            if importer.ended() {
                anyhow::bail!("the link import thread ended");
            }
        }
        health.tick()?;
        while let Ok(Some(sample)) = inbound.try_recv() {
            let key = sample.key_expr().as_str().to_string();
            let why = match json::envelope(&sample.payload().to_bytes()) {
                Err(e) => e.to_string(),
                Ok(_) => "the bridge takes no input on it (remote peers only read)".to_string(),
            };
            // Said once per key and reason (at most a hundred), counted always.
            if said.len() < 100 && said.insert((key.clone(), why.clone())) {
                eprintln!("icrflow-bridge: ignored a remote message on {key}: {why}");
            }
            health.refuse(format!("remote message on {key}: {why}"));
        }
        for (forward, publisher) in &forwards {
            let mut failed = None;
            let mut keep = |r: Result<()>| {
                if let Err(e) = r {
                    failed.get_or_insert(e);
                }
            };
            let n = forward.drain(rig, &mut text, &mut |json| {
                keep(json.and_then(|bytes| {
                    publisher
                        .put(bytes)
                        .wait()
                        .map_err(|e| anyhow!("zenoh put: {e}"))
                }))
            })?;
            health.processed += n as u64;
            if let Some(e) = failed {
                // A put that fails (the session closing) is counted, never fatal: monitoring
                // must not take the pipeline down.
                health.refuse(format!("{}: {e:#}", publisher.key_expr()));
            }
        }
        Ok(())
    })
    .context("bridge loop");
    let stopped = importer.map_or(Ok(()), link::Importer::stop);
    stopped.and(served)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn zenohs_errors_are_said_without_its_internals() {
        let raw = "Json5Err(Message { msg: \"invalid endpoint metadata\", location: Some(Position { line: 1, column: 2 }) })";
        assert_eq!(words(&raw), "invalid endpoint metadata");
        let raw = "Unable to connect to any of [tcp/127.0.0.1:7447]!  at /root/.cargo/registry/src/index.crates.io-1949cf8c6b5b557f/zenoh-1.10.2/src/net/runtime/orchestrator.rs:447.";
        assert_eq!(
            words(&raw),
            "Unable to connect to any of [tcp/127.0.0.1:7447]"
        );
        assert_eq!(words(&"plain"), "plain");
    }

    #[test]
    fn a_bad_endpoint_is_refused_in_our_words() {
        let e = client_config("tcp/127.0.0.1:7447#=x", None)
            .err()
            .map(|e| format!("{e:#}"));
        if let Some(e) = e {
            assert!(e.starts_with("Zenoh refused the setting"), "{e}");
            assert!(!e.contains("Json5Err") && !e.contains(".cargo"), "{e}");
        }
    }
}
