"""An external Zenoh client of a running pipeline, as any user's would be: the Python
`eclipse-zenoh` package (pinned in bench/requirements.txt to the Rust crate's version), no
code of ours. Used by tests/zenoh.rs.

    python tests/zenoh_client.py ENDPOINT RIG SECONDS TOPIC...
    python tests/zenoh_client.py --stall ENDPOINT RIG SECONDS
    python tests/zenoh_client.py --measure ENDPOINT RIG SECONDS
    python tests/zenoh_client.py --answer ENDPOINT RIG SECONDS
    python tests/zenoh_client.py --ask ENDPOINT RIG
    python tests/zenoh_client.py --put ENDPOINT KEY HEX
    python tests/zenoh_client.py --keys ENDPOINT RIG SECONDS KEYEXPR...

--answer declares a queryable on icrflow/RIG/hand_command for SECONDS, as a peer pretending
to speak for the hand would; --ask queries that key expression through the pipeline's
session and prints how many replies came; --put puts the bytes HEX (hex digits) on KEY and
waits a second (tests/two_hosts.rs: bad input on a split pipeline's link topics). --keys
opens one session per KEYEXPR (separate sessions: a session delivers its own matching
samples to all its subscribers, which would hide a declaration the pipeline refused), each
subscribing to its KEYEXPR, until each has received every monitoring topic it matches 5
times or SECONDS passed; then another session puts a marked hand command on icrflow/RIG/hand_command
and on icrflow/RIG/marker/put (beyond the monitoring keys' icrflow/RIG/*, where the main
form's decoding would count it as an error in the same run), and after a second it prints per KEYEXPR the samples and topics
received and how many of them were the marked puts (a pipeline that passed them on to its
other clients would let a remote peer write to them). The third (bench/pipeline.sh) counts every topic's messages for SECONDS and the delay from
each message's publication on the local bus (its time_ns) to its arrival here, and prints them
as JSON. With ZENOH_USER and ZENOH_PASSWORD in the environment, the client authenticates with them
(the pipeline's zenoh.users_file). The second form is a peer that stops reading: its subscriber's callback blocks on the first
sample, for SECONDS, while the run keeps publishing at the loop rate.

Connects to ENDPOINT as a client, subscribes to icrflow/RIG/* (the monitoring topics), and decodes every sample as
the monitoring JSON of the README (an object with schema 1, its topic and rig). Stops when
every TOPIC has been received and decoded at least 20 times, or after SECONDS. Then it tries
to write, as a hostile or mistaken client would: it declares a queryable on
icrflow/RIG/hand_command, puts a well-formed hand command there, then a malformed one and one
of another schema, and waits a second. Prints one JSON object: per key expression the samples
received and decoded, the decoding errors (at most ten), and what it put. Exit 0 when every
TOPIC arrived, decoded, 20 times; 1 otherwise.
"""

import json
import os
import sys
import threading
import time

import zenoh

WANTED = 20


def login(config: "zenoh.Config") -> None:
    """Authenticates with ZENOH_USER / ZENOH_PASSWORD when both are set."""
    user, password = os.environ.get("ZENOH_USER"), os.environ.get("ZENOH_PASSWORD")
    if user and password:
        config.insert_json5("transport/auth/usrpwd/user", json.dumps(user))
        config.insert_json5("transport/auth/usrpwd/password", json.dumps(password))


def stall(endpoint: str, rig: str, seconds: float) -> int:
    config = client_config(endpoint)
    got = threading.Event()

    def on_sample(sample: "zenoh.Sample") -> None:
        if not got.is_set():
            got.set()
            print(json.dumps({"stalled": True}), flush=True)
        time.sleep(seconds)  # never returns in time: the session's receive path is stuck

    with zenoh.open(config) as session:
        session.declare_subscriber(f"icrflow/{rig}/*", on_sample)
        time.sleep(seconds)
    return 0 if got.is_set() else 1


def measure(endpoint: str, rig: str, seconds: float) -> int:
    config = client_config(endpoint)
    lock = threading.Lock()
    delays: dict[str, list[float]] = {}

    def on_sample(sample: "zenoh.Sample") -> None:
        now = time.time_ns()
        obj = json.loads(sample.payload.to_bytes())
        with lock:
            delays.setdefault(obj["topic"], []).append((now - obj["time_ns"]) * 1e-3)

    with zenoh.open(config) as session:
        session.declare_subscriber(f"icrflow/{rig}/*", on_sample)
        time.sleep(seconds)
    out = {}
    with lock:
        for topic, d in sorted(delays.items()):
            d.sort()
            out[topic] = {
                "messages": len(d),
                "rate_hz": len(d) / seconds,
                "delay_us": {"p50": d[len(d) // 2], "p99": d[int(0.99 * (len(d) - 1))], "max": d[-1]},
            }
    print(json.dumps(out))
    return 0 if out else 1


def client_config(endpoint: str) -> "zenoh.Config":
    config = zenoh.Config()
    config.insert_json5("mode", json.dumps("client"))
    config.insert_json5("connect/endpoints", json.dumps([endpoint]))
    config.insert_json5("scouting/multicast/enabled", "false")
    login(config)
    return config


def answer(endpoint: str, rig: str, seconds: float) -> int:
    key = f"icrflow/{rig}/hand_command"
    with zenoh.open(client_config(endpoint)) as session:
        queryable = session.declare_queryable(key, lambda query: query.reply(key, "{}"))
        time.sleep(seconds)
        queryable.undeclare()
    return 0


def ask(endpoint: str, rig: str) -> int:
    key = f"icrflow/{rig}/hand_command"
    with zenoh.open(client_config(endpoint)) as session:
        replies = list(session.get(key, timeout=2.0))
        ok = sum(1 for r in replies if r.ok is not None)
    print(json.dumps({"replies": ok}))
    return 0


def put(endpoint: str, key: str, payload: str) -> int:
    with zenoh.open(client_config(endpoint)) as session:
        session.put(key, bytes.fromhex(payload))
        time.sleep(1.0)
    print(json.dumps({"put": key}))
    return 0


MARK = "icrflow-test-foreign-put"


def keys(endpoint: str, rig: str, seconds: float, exprs: list[str]) -> int:
    deadline = time.monotonic() + seconds
    lock = threading.Lock()
    seen: dict[str, dict[str, int]] = {e: {} for e in exprs}
    foreign: dict[str, int] = {e: 0 for e in exprs}
    wanted = ["joint_state", "grasp_state", "wrench_space", "plan_step", "hand_command", "node_health"]

    def on_sample_of(expr: str):
        def on_sample(sample: "zenoh.Sample") -> None:
            key = str(sample.key_expr)
            payload = sample.payload.to_bytes()
            with lock:
                seen[expr][key] = seen[expr].get(key, 0) + 1
                if MARK.encode() in payload:
                    foreign[expr] += 1
        return on_sample

    # The monitoring keys each key expression matches.
    matching = {
        e: [k for k in (f"icrflow/{rig}/{t}" for t in wanted)
            if zenoh.KeyExpr(e).intersects(zenoh.KeyExpr(k))]
        for e in exprs
    }

    def done() -> bool:
        with lock:
            return all(seen[e].get(k, 0) >= 5 for e in exprs for k in matching[e])

    sessions = []
    try:
        for expr in exprs:
            session = zenoh.open(client_config(endpoint))
            sessions.append(session)
            session.declare_subscriber(expr, on_sample_of(expr))
        while time.monotonic() < deadline and not done():
            time.sleep(0.05)
        complete = done()
        command = f"icrflow/{rig}/hand_command"
        marked = json.dumps({
            "schema": 1, "topic": "hand_command", "rig": rig, "sequence": 2**62,
            "time_ns": time.time_ns(), "origin_ns": 0, "mode": "track", "reason": MARK,
            "quality": 1.0, "latency_us": 0.0, "fingers": [],
        })
        put_keys = [command, f"icrflow/{rig}/marker/put"]
        with zenoh.open(client_config(endpoint)) as writer:
            for _ in range(5):
                for key in put_keys:
                    writer.put(key, marked)
                time.sleep(0.1)
            time.sleep(1.0)
    finally:
        for session in sessions:
            session.close()
    with lock:
        print(json.dumps({
            "keys": {
                e: {"samples": sum(seen[e].values()), "topics": seen[e], "foreign": foreign[e]}
                for e in exprs
            },
            "complete": complete,
            "put": {k: 5 for k in put_keys},
        }))
    return 0


def main() -> int:
    if sys.argv[1] == "--keys":
        return keys(sys.argv[2], sys.argv[3], float(sys.argv[4]), sys.argv[5:])
    if sys.argv[1] == "--put":
        return put(sys.argv[2], sys.argv[3], sys.argv[4])
    if sys.argv[1] == "--answer":
        return answer(sys.argv[2], sys.argv[3], float(sys.argv[4]))
    if sys.argv[1] == "--ask":
        return ask(sys.argv[2], sys.argv[3])
    if sys.argv[1] == "--measure":
        return measure(sys.argv[2], sys.argv[3], float(sys.argv[4]))
    if sys.argv[1] == "--stall":
        return stall(sys.argv[2], sys.argv[3], float(sys.argv[4]))
    endpoint, rig, seconds, *topics = sys.argv[1:]
    deadline = time.monotonic() + float(seconds)
    config = client_config(endpoint)
    lock = threading.Lock()
    received: dict[str, int] = {}
    decoded: dict[str, int] = {}
    errors: list[str] = []

    def on_sample(sample: "zenoh.Sample") -> None:
        key = str(sample.key_expr)
        topic = key.rsplit("/", 1)[-1]
        with lock:
            received[key] = received.get(key, 0) + 1
        try:
            obj = json.loads(sample.payload.to_bytes())
            if not isinstance(obj, dict):
                raise ValueError("not a JSON object")
            if obj.get("schema") != 1:
                raise ValueError(f"schema {obj.get('schema')!r}")
            if obj.get("topic") != topic or obj.get("rig") != rig:
                raise ValueError(f"topic/rig {obj.get('topic')!r}/{obj.get('rig')!r}")
            for field in ("sequence", "time_ns", "origin_ns"):
                if not isinstance(obj.get(field), int):
                    raise ValueError(f"{field} missing")
        except Exception as e:  # noqa: BLE001 - every failure is reported
            with lock:
                if len(errors) < 10:
                    errors.append(f"{key}: {e}")
            return
        with lock:
            decoded[key] = decoded.get(key, 0) + 1

    def done() -> bool:
        with lock:
            return all(decoded.get(f"icrflow/{rig}/{t}", 0) >= WANTED for t in topics)

    command = f"icrflow/{rig}/hand_command"
    hold = {
        "schema": 1, "topic": "hand_command", "rig": rig, "sequence": 2**62,
        "time_ns": time.time_ns(), "origin_ns": 0, "mode": "track", "reason": "",
        "quality": 1.0, "latency_us": 0.0, "fingers": [],
    }
    puts = [json.dumps(hold), "{not json", json.dumps({**hold, "schema": 99})]
    try:
        opened = zenoh.open(config)
    except Exception as e:  # noqa: BLE001 - a refused connection is a result, not a crash
        print(json.dumps({"received": {}, "decoded": {}, "errors": [f"open: {e}"], "ok": False}))
        return 1
    with opened as session:
        subscriber = session.declare_subscriber(f"icrflow/{rig}/*", on_sample)
        while time.monotonic() < deadline and not done():
            time.sleep(0.05)
        subscriber.undeclare()
        queryable = session.declare_queryable(command, lambda query: query.reply(command, "{}"))
        for payload in puts:
            session.put(command, payload)
        time.sleep(1.0)
        queryable.undeclare()
    ok = done()
    with lock:
        print(json.dumps({
            "received": received, "decoded": decoded, "errors": errors, "ok": ok,
            "put": {command: len(puts)},
        }))
    return 0 if ok else 1


if __name__ == "__main__":
    sys.exit(main())
