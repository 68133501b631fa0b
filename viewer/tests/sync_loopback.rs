//! A real zenoh session on loopback plays the server: it answers the snapshot key from its model and publishes
//! mesh deltas and tool states. A `ViewerClient` (started before the "server", which may come up later) must
//! converge to the published state, detect a skipped delta as a gap, re-query the snapshot and reconverge.
//! Every wait has a timeout; nothing asserts on latency.

// This whole file is test code: a panic is a test failure (clippy's allow-unwrap-in-tests only covers #[test] fns).
#![allow(clippy::unwrap_used, clippy::expect_used)]

mod common;

use std::net::TcpListener;
use std::sync::atomic::{AtomicU64, Ordering};
use std::sync::{Arc, Mutex};
use std::time::{Duration, Instant};

use common::{diff_delta, quantize_all, sheet_positions_mm, sheet_snapshot};
use sinew_protocol::codec::encode_to_vec;
use sinew_protocol::keys::SceneKeys;
use sinew_protocol::network::NetworkOptions;
use sinew_protocol::{Role, SceneSnapshot, ToolStates};
use sinew_viewer::{ViewerClient, ViewerConfig, ViewerHandle};
use zenoh::Wait;
use zenoh::qos::CongestionControl;

const N: usize = 10;
const WAIT: Duration = Duration::from_secs(20);

fn free_port() -> u16 {
    TcpListener::bind("127.0.0.1:0")
        .and_then(|l| l.local_addr())
        .map(|a| a.port())
        .expect("no free loopback port")
}

fn wait_until(timeout: Duration, mut done: impl FnMut() -> bool) -> bool {
    let deadline = Instant::now() + timeout;
    while Instant::now() < deadline {
        if done() {
            return true;
        }
        std::thread::sleep(Duration::from_millis(20));
    }
    done()
}

/// The authoritative state of the fake server.
struct Model {
    positions_mm: Vec<[f32; 3]>,
    positions_q: Vec<[u16; 3]>,
    frame: u64,
    object_frame: u64,
    tool_mm: [f32; 3],
}

impl Model {
    fn snapshot(&self) -> SceneSnapshot {
        let mut snapshot = sheet_snapshot(self.positions_q.clone(), N, self.frame, self.tool_mm);
        snapshot.objects[0].frame = self.object_frame;
        snapshot
    }

    fn tool_states(&self) -> ToolStates {
        self.snapshot().tool_states
    }
}

struct FakeServer {
    session: zenoh::Session,
    model: Arc<Mutex<Model>>,
    queries: Arc<AtomicU64>,
    _queryable: zenoh::query::Queryable<()>,
    _token: zenoh::liveliness::LivelinessToken,
    deltas: zenoh::pubsub::Publisher<'static>,
    tools: zenoh::pubsub::Publisher<'static>,
    keys: SceneKeys,
}

impl FakeServer {
    fn start(endpoint: &str) -> Self {
        let options = NetworkOptions {
            listen: vec![endpoint.to_owned()],
            ..NetworkOptions::default()
        };
        let mut config = zenoh::Config::default();
        for (key, value) in options.config_entries() {
            config.insert_json5(key, &value).unwrap();
        }
        let session = zenoh::open(config).wait().unwrap();
        let keys = SceneKeys::new("pad").unwrap();
        let positions_mm = sheet_positions_mm(N);
        let model = Arc::new(Mutex::new(Model {
            positions_q: quantize_all(&positions_mm),
            positions_mm,
            frame: 100,
            object_frame: 100,
            tool_mm: [0.0, 0.0, 10.0],
        }));
        let queries = Arc::new(AtomicU64::new(0));
        let (for_queries, counter) = (Arc::clone(&model), Arc::clone(&queries));
        let snapshot_key = keys.snapshot();
        let reply_key = snapshot_key.clone();
        let queryable = session
            .declare_queryable(&snapshot_key)
            .callback(move |query| {
                counter.fetch_add(1, Ordering::SeqCst);
                let payload = encode_to_vec(
                    sinew_protocol::InstanceId(1),
                    &for_queries.lock().unwrap().snapshot(),
                );
                query.reply(&reply_key, payload).wait().unwrap();
            })
            .wait()
            .unwrap();
        let token = session
            .liveliness()
            .declare_token(keys.presence(Role::Server, "fake-server").unwrap())
            .wait()
            .unwrap();
        let deltas = session
            .declare_publisher(keys.mesh_delta("pad").unwrap())
            .congestion_control(CongestionControl::Block)
            .wait()
            .unwrap();
        let tools = session.declare_publisher(keys.tools()).wait().unwrap();
        Self {
            session,
            model,
            queries,
            _queryable: queryable,
            _token: token,
            deltas,
            tools,
            keys,
        }
    }

    /// Advance one publish frame: move a few vertices by more than a quantum, publish the delta unless
    /// `lose_delta`, and the tool states. Under the model lock, so a snapshot never splits a frame.
    fn step(&self, rng: &mut fastrand::Rng, lose_delta: bool) {
        let mut model = self.model.lock().unwrap();
        model.frame += 1;
        for _ in 0..3 {
            let v = rng.usize(0..model.positions_mm.len());
            model.positions_mm[v][2] += if rng.bool() { 0.5 } else { -0.5 };
        }
        model.tool_mm[0] += 0.1;
        let now_q = quantize_all(&model.positions_mm);
        let delta = diff_delta(&model.positions_q, &now_q, model.object_frame, model.frame);
        assert!(!delta.indices.is_empty());
        model.positions_q = now_q;
        model.object_frame = model.frame;
        if !lose_delta {
            self.deltas
                .put(encode_to_vec(sinew_protocol::InstanceId(1), &delta))
                .wait()
                .unwrap();
        }
        self.tools
            .put(encode_to_vec(
                sinew_protocol::InstanceId(1),
                &model.tool_states(),
            ))
            .wait()
            .unwrap();
    }

    fn queries(&self) -> u64 {
        self.queries.load(Ordering::SeqCst)
    }

    fn converged(&self, viewer: &ViewerHandle) -> bool {
        let model = self.model.lock().unwrap();
        viewer.with_replica(|r| {
            r.quantized(0) == model.positions_q.as_slice()
                && r.object(0).map(|o| o.frame()) == Some(model.object_frame)
                && r.tool_states().frame == model.frame
                && r.tool_states().tools[0].position_mm == model.tool_mm
        })
    }

    fn viewer_present(&self, id: &str) -> bool {
        let Ok(replies) = self
            .session
            .liveliness()
            .get(self.keys.all_presence(Role::Viewer))
            .timeout(Duration::from_secs(1))
            .wait()
        else {
            return false;
        };
        let mut found = false;
        while let Ok(reply) = replies.recv() {
            if let Ok(sample) = reply.result() {
                found |= self
                    .keys
                    .presence_id_of(Role::Viewer, sample.key_expr().as_str())
                    == Some(id);
            }
        }
        found
    }
}

#[test]
fn viewer_converges_and_recovers_from_a_skipped_delta() {
    let endpoint = format!("tcp/127.0.0.1:{}", free_port());
    let mut rng = fastrand::Rng::with_seed(42);

    // The viewer starts first: the server may come up later.
    let mut config = ViewerConfig::new("pad", "test-viewer");
    config.network = NetworkOptions {
        connect: vec![endpoint.clone()],
        ..NetworkOptions::default()
    };
    config.snapshot_timeout = Duration::from_millis(500);
    let mut viewer = ViewerClient::start(config).expect("viewer start");
    std::thread::sleep(Duration::from_millis(300));
    assert!(!viewer.stats().has_snapshot);

    let server = FakeServer::start(&endpoint);
    assert!(
        viewer.wait_for_snapshot(WAIT),
        "no snapshot within {WAIT:?}: {:?}",
        viewer.stats()
    );
    assert!(server.queries() >= 1);
    assert!(
        wait_until(WAIT, || server.viewer_present("test-viewer")),
        "the viewer's presence token is not visible"
    );

    // Live updates.
    for _ in 0..30 {
        server.step(&mut rng, false);
        std::thread::sleep(Duration::from_millis(5));
    }
    assert!(
        wait_until(WAIT, || server.converged(&viewer)),
        "replica did not converge: {:?}",
        viewer.stats()
    );
    let stats = viewer.stats();
    assert!(stats.deltas_applied > 0, "{stats:?}");
    assert!(stats.bytes_received > 0);
    assert_eq!(stats.decode_errors.total(), 0);
    assert!(stats.replica_error_bound_mm > 0.0 && stats.replica_error_bound_mm < 0.01);

    // Lose one delta: the next one reveals the gap, the viewer re-queries and reconverges.
    let queries_before = server.queries();
    let gaps_before = stats.gaps;
    server.step(&mut rng, true);
    for _ in 0..5 {
        server.step(&mut rng, false);
        std::thread::sleep(Duration::from_millis(5));
    }
    assert!(
        wait_until(WAIT, || server.queries() > queries_before
            && server.converged(&viewer)),
        "no re-snapshot and reconvergence after a lost delta: queries {} -> {}, {:?}",
        queries_before,
        server.queries(),
        viewer.stats()
    );
    assert!(viewer.stats().gaps > gaps_before, "{:?}", viewer.stats());

    // Garbage on the delta key is counted and changes nothing.
    let garbage = server
        .session
        .declare_publisher(server.keys.mesh_delta("pad").unwrap())
        .wait()
        .unwrap();
    garbage.put(vec![1u8, 0, 4, 0xff, 0xff]).wait().unwrap();
    assert!(
        wait_until(WAIT, || viewer.stats().decode_errors.total() >= 1),
        "garbage not counted: {:?}",
        viewer.stats()
    );
    assert!(server.converged(&viewer));

    // Stopping withdraws the presence token.
    viewer.stop();
    assert!(
        wait_until(WAIT, || !server.viewer_present("test-viewer")),
        "presence token still visible after stop"
    );
}
