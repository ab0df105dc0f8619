//! The server and the client on loopback, including the faults: malformed
//! and oversized lines, clients and servers vanishing mid-turn, two clients,
//! wrong token, wrong version. Every wait here is bounded.

use std::io::{BufRead, BufReader, Read, Write};
use std::net::{SocketAddr, TcpListener, TcpStream};
use std::thread;
use std::time::{Duration, Instant};

use voxoct_turntable::protocol::MAX_LINE_LEN;
use voxoct_turntable::{
    ClientTimeouts, ErrorCode, RemoteTurntable, ServerConfig, ServerHandle, SimulatedTurntable,
    Turntable, TurntableError, serve,
};

const T: Duration = Duration::from_secs(5);

fn config(token: Option<&str>) -> ServerConfig {
    ServerConfig {
        token: token.map(str::to_string),
        handshake_timeout: Duration::from_millis(500),
        idle_timeout: Duration::from_secs(10),
        ..ServerConfig::default()
    }
}

fn start(table: SimulatedTurntable, token: Option<&str>) -> ServerHandle {
    let listener = TcpListener::bind("127.0.0.1:0").unwrap();
    serve(listener, table, config(token)).unwrap()
}

fn quick() -> ClientTimeouts {
    ClientTimeouts {
        connect: Duration::from_secs(2),
        reply: Duration::from_secs(2),
        rotate_margin: Duration::from_secs(1),
    }
}

/// Connects, retrying while the table is busy, for at most `limit`.
fn connect_retry(addr: SocketAddr, token: Option<&str>, limit: Duration) -> RemoteTurntable {
    let start = Instant::now();
    loop {
        match RemoteTurntable::connect(addr, token, quick()) {
            Ok(c) => return c,
            Err(TurntableError::Busy(_)) if start.elapsed() < limit => {
                thread::sleep(Duration::from_millis(20));
            }
            Err(e) => panic!("connect failed after {:?}: {e}", start.elapsed()),
        }
    }
}

struct Raw {
    reader: BufReader<TcpStream>,
    stream: TcpStream,
}

impl Raw {
    fn connect(addr: SocketAddr) -> Self {
        let stream = TcpStream::connect(addr).unwrap();
        stream.set_read_timeout(Some(T)).unwrap();
        Self {
            reader: BufReader::new(stream.try_clone().unwrap()),
            stream,
        }
    }

    fn send(&mut self, bytes: &[u8]) {
        self.stream.write_all(bytes).unwrap();
    }

    fn line(&mut self) -> String {
        let mut s = String::new();
        self.reader.read_line(&mut s).unwrap();
        assert!(s.len() <= MAX_LINE_LEN, "reply too long: {s:?}");
        s
    }

    fn ask(&mut self, line: &str) -> String {
        self.send(format!("{line}\n").as_bytes());
        self.line()
    }

    /// The server closed: EOF (or a reset) within the read timeout.
    fn assert_closed(&mut self) {
        let mut rest = Vec::new();
        match self.reader.read_to_end(&mut rest) {
            Ok(_) => assert!(rest.is_empty(), "unexpected {rest:?}"),
            Err(e) => assert_eq!(e.kind(), std::io::ErrorKind::ConnectionReset, "{e}"),
        }
    }
}

#[test]
fn remote_table_behaves_like_a_local_one() {
    let server = start(SimulatedTurntable::default(), Some("s3cret"));
    let remote = RemoteTurntable::connect(server.local_addr(), Some("s3cret"), quick()).unwrap();
    let mut table: Box<dyn Turntable> = Box::new(remote);
    for _ in 0..8 {
        assert_eq!(table.rotate_by(45.0, T).unwrap(), 45.0);
    }
    assert_eq!(table.angle_deg().unwrap(), 0.0);
    assert_eq!(table.rotate_by(1.0, T).unwrap(), 0.9);
    assert_eq!(table.rotate_by(-91.0, T).unwrap(), -90.9);
    assert_eq!(table.angle_deg().unwrap(), 270.0);
    table.home().unwrap();
    assert_eq!(table.angle_deg().unwrap(), 0.0);
    // Errors arrive as the same variants as locally.
    assert!(matches!(
        table.rotate_by(f64::NAN, T),
        Err(TurntableError::BadAngle { .. })
    ));
    server.shutdown();
}

#[test]
fn malformed_requests_get_an_error_and_the_session_goes_on() {
    let server = start(SimulatedTurntable::default(), None);
    let mut c = Raw::connect(server.local_addr());
    assert_eq!(c.ask("VOXOCT-TT/1"), "OK VOXOCT-TT/1\n");
    for bad in [
        "FOO",
        "",
        "rotate 5",
        "ROTATE",
        "ROTATE abc",
        "ROTATE 5 0",
        "PING PONG",
    ] {
        assert!(c.ask(bad).starts_with("ERR BAD_REQUEST "), "{bad:?}");
    }
    assert!(c.ask("ROTATE nan").starts_with("ERR BAD_ANGLE "));
    assert!(c.ask("ROTATE 1e9").starts_with("ERR BAD_ANGLE "));
    c.send(b"\xff\xfe ROTATE 1\n");
    assert!(c.line().starts_with("ERR BAD_REQUEST "));
    assert_eq!(c.ask("ROTATE 90 1000\r"), "OK 90\n", "CR LF is accepted");
    assert_eq!(c.ask("PING"), "OK PONG\n");
    assert_eq!(c.ask("ANGLE"), "OK 90\n");
    assert_eq!(c.ask("QUIT"), "OK BYE\n");
    c.assert_closed();
    server.shutdown();
}

#[test]
fn an_oversized_line_is_answered_then_closed_and_the_server_keeps_serving() {
    let server = start(SimulatedTurntable::default(), None);
    let addr = server.local_addr();
    // In the session.
    let mut c = Raw::connect(addr);
    assert_eq!(c.ask("VOXOCT-TT/1"), "OK VOXOCT-TT/1\n");
    let mut huge = vec![b'7'; 100_000];
    huge.push(b'\n');
    c.send(&huge);
    assert!(c.line().starts_with("ERR TOO_LONG "));
    c.assert_closed();
    // As the handshake, without any line end.
    let mut c = Raw::connect(addr);
    c.send(&vec![b'V'; 4 * MAX_LINE_LEN]);
    assert!(c.line().starts_with("ERR TOO_LONG "));
    c.assert_closed();
    // The server still serves.
    let mut ok = connect_retry(addr, None, T);
    ok.ping().unwrap();
    assert_eq!(ok.rotate_by(45.0, T).unwrap(), 45.0);
    server.shutdown();
}

#[test]
fn a_client_vanishing_mid_turn_lets_the_turn_finish() {
    // 180°/s: a 90° turn takes 0.5 s.
    let table = SimulatedTurntable::default().with_speed(180.0).unwrap();
    let server = start(table, None);
    let addr = server.local_addr();
    let started = Instant::now();
    {
        let mut c = Raw::connect(addr);
        assert_eq!(c.ask("VOXOCT-TT/1"), "OK VOXOCT-TT/1\n");
        c.send(b"ROTATE 90 5000\n");
        thread::sleep(Duration::from_millis(50));
    } // dropped mid-turn
    // While the turn runs the table is still owned: others are refused.
    match RemoteTurntable::connect(addr, None, quick()) {
        Err(TurntableError::Busy(_)) => {}
        other => panic!("expected Busy during the turn, got {other:?}"),
    }
    let mut next = connect_retry(addr, None, T);
    assert!(
        started.elapsed() >= Duration::from_millis(450),
        "turn finished first"
    );
    assert!(started.elapsed() < Duration::from_secs(3));
    assert_eq!(next.angle_deg().unwrap(), 90.0, "the turn completed");
    server.shutdown();
}

/// A fake server that handshakes, reads one request, then misbehaves.
fn fake_server(after_request: impl FnOnce(TcpStream) + Send + 'static) -> SocketAddr {
    let listener = TcpListener::bind("127.0.0.1:0").unwrap();
    let addr = listener.local_addr().unwrap();
    thread::spawn(move || {
        let (stream, _) = listener.accept().unwrap();
        stream.set_read_timeout(Some(T)).unwrap();
        let mut reader = BufReader::new(stream.try_clone().unwrap());
        let mut line = String::new();
        reader.read_line(&mut line).unwrap();
        (&stream).write_all(b"OK VOXOCT-TT/1\n").unwrap();
        line.clear();
        reader.read_line(&mut line).unwrap();
        after_request(stream);
    });
    addr
}

#[test]
fn a_server_dying_mid_turn_gives_a_clear_error_at_once() {
    let addr = fake_server(|stream| {
        thread::sleep(Duration::from_millis(100));
        drop(stream); // the process died: the kernel closes the socket
    });
    let mut c = RemoteTurntable::connect(addr, None, quick()).unwrap();
    let start = Instant::now();
    let err = c.rotate_by(90.0, Duration::from_secs(30)).unwrap_err();
    assert!(matches!(err, TurntableError::Disconnected(_)), "{err}");
    assert!(
        start.elapsed() < Duration::from_secs(2),
        "{:?}",
        start.elapsed()
    );
    assert!(!c.is_connected());
    // Later calls fail at once, without touching the network.
    assert!(matches!(
        c.angle_deg(),
        Err(TurntableError::Disconnected(_))
    ));
}

#[test]
fn a_silent_server_times_out_and_never_hangs() {
    let (keep_tx, keep_rx) = std::sync::mpsc::channel::<()>();
    let addr = fake_server(move |stream| {
        // Holds the connection open and says nothing (a frozen Pi).
        let _ = keep_rx.recv_timeout(Duration::from_secs(10));
        drop(stream);
    });
    let timeouts = ClientTimeouts {
        rotate_margin: Duration::from_millis(200),
        ..quick()
    };
    let mut c = RemoteTurntable::connect(addr, None, timeouts).unwrap();
    let start = Instant::now();
    let err = c.rotate_by(90.0, Duration::from_millis(300)).unwrap_err();
    let took = start.elapsed();
    assert!(matches!(err, TurntableError::Timeout { .. }), "{err}");
    assert!(
        took >= Duration::from_millis(450) && took < Duration::from_secs(2),
        "{took:?}"
    );
    drop(keep_tx);
}

#[test]
fn a_second_client_is_refused_until_the_first_leaves() {
    let server = start(SimulatedTurntable::default(), Some("tok"));
    let addr = server.local_addr();
    let mut a = RemoteTurntable::connect(addr, Some("tok"), quick()).unwrap();
    let err = RemoteTurntable::connect(addr, Some("tok"), quick()).unwrap_err();
    assert!(matches!(err, TurntableError::Busy(_)), "{err}");
    // A wrong token is told so even while busy.
    let err = RemoteTurntable::connect(addr, Some("bad"), quick()).unwrap_err();
    assert!(matches!(err, TurntableError::Unauthorised), "{err}");
    a.rotate_by(45.0, T).unwrap();
    a.close().unwrap();
    let mut b = connect_retry(addr, Some("tok"), T);
    assert_eq!(b.angle_deg().unwrap(), 45.0);
    drop(b); // dropped without QUIT: the table is freed too
    let mut c = connect_retry(addr, Some("tok"), T);
    c.ping().unwrap();
    server.shutdown();
}

#[test]
fn a_wrong_or_missing_token_is_refused() {
    let server = start(SimulatedTurntable::default(), Some("s3cret"));
    let addr = server.local_addr();
    for token in [None, Some("s3creT"), Some("s3cret2"), Some("x")] {
        let err = RemoteTurntable::connect(addr, token, quick()).unwrap_err();
        assert!(
            matches!(err, TurntableError::Unauthorised),
            "{token:?}: {err}"
        );
    }
    let mut raw = Raw::connect(addr);
    assert!(
        raw.ask("VOXOCT-TT/1 guess")
            .starts_with("ERR UNAUTHORISED ")
    );
    raw.assert_closed();
    // A token with a space cannot even be sent.
    assert!(matches!(
        RemoteTurntable::connect(addr, Some("a b"), quick()),
        Err(TurntableError::Config(_))
    ));
    let mut ok = RemoteTurntable::connect(addr, Some("s3cret"), quick()).unwrap();
    ok.ping().unwrap();
    server.shutdown();
}

#[test]
fn another_protocol_version_is_refused_clearly() {
    let server = start(SimulatedTurntable::default(), None);
    let addr = server.local_addr();
    let mut raw = Raw::connect(addr);
    let reply = raw.ask("VOXOCT-TT/2");
    assert!(reply.starts_with("ERR VERSION "), "{reply}");
    assert!(
        reply.contains("VOXOCT-TT/1") && reply.contains("VOXOCT-TT/2"),
        "{reply}"
    );
    raw.assert_closed();
    let mut raw = Raw::connect(addr);
    assert!(raw.ask("HELLO").starts_with("ERR BAD_REQUEST "));
    raw.assert_closed();
    server.shutdown();

    // A client meeting a newer server.
    for answer in [
        "ERR VERSION this server speaks VOXOCT-TT/2",
        "OK VOXOCT-TT/2",
    ] {
        let listener = TcpListener::bind("127.0.0.1:0").unwrap();
        let addr = listener.local_addr().unwrap();
        let answer = answer.to_string();
        let t = thread::spawn(move || {
            let (mut s, _) = listener.accept().unwrap();
            let mut line = String::new();
            BufReader::new(s.try_clone().unwrap())
                .read_line(&mut line)
                .unwrap();
            s.write_all(format!("{answer}\n").as_bytes()).unwrap();
        });
        let err = RemoteTurntable::connect(addr, None, quick()).unwrap_err();
        assert!(matches!(err, TurntableError::Version(_)), "{err}");
        t.join().unwrap();
    }
}

#[test]
fn a_silent_connection_is_closed_after_the_handshake_timeout() {
    let server = start(SimulatedTurntable::default(), None);
    let mut raw = Raw::connect(server.local_addr());
    let start = Instant::now();
    assert!(raw.line().starts_with("ERR TIMEOUT "));
    raw.assert_closed();
    assert!(start.elapsed() < Duration::from_secs(3));
    server.shutdown();
}

#[test]
fn a_too_short_timeout_is_a_timeout_and_the_session_survives() {
    let table = SimulatedTurntable::default().with_speed(90.0).unwrap();
    let server = start(table, None);
    let mut c = RemoteTurntable::connect(server.local_addr(), None, quick()).unwrap();
    let err = c.rotate_by(90.0, Duration::from_millis(100)).unwrap_err();
    assert_eq!(err.code(), ErrorCode::Timeout);
    // Refused up front: the message says so, and no "timed out after".
    assert!(err.to_string().contains("refused before moving"), "{err}");
    assert!(!err.to_string().contains("timed out after"), "{err}");
    assert_eq!(c.angle_deg().unwrap(), 0.0, "nothing moved");
    c.ping().unwrap();
    server.shutdown();
}

#[test]
fn garbage_from_the_server_is_a_protocol_error() {
    let addr = fake_server(|mut stream| {
        let _ = stream.write_all(&[b'x'; 4 * MAX_LINE_LEN]);
        thread::sleep(Duration::from_millis(300));
    });
    let mut c = RemoteTurntable::connect(addr, None, quick()).unwrap();
    let err = c.angle_deg().unwrap_err();
    assert!(matches!(err, TurntableError::Protocol(_)), "{err}");
}

#[test]
fn a_full_server_evicts_a_connection_in_its_handshake_and_shutdown_is_prompt() {
    let listener = TcpListener::bind("127.0.0.1:0").unwrap();
    let cfg = ServerConfig {
        max_connections: 2,
        ..config(None)
    };
    let server = serve(listener, SimulatedTurntable::default(), cfg).unwrap();
    let addr = server.local_addr();
    let mut session = RemoteTurntable::connect(addr, None, quick()).unwrap();
    let mut lurker = Raw::connect(addr); // in its handshake
    thread::sleep(Duration::from_millis(50));
    let mut third = Raw::connect(addr);
    // The lurker is closed to make room; the third gets in, and is told the table is busy.
    assert_eq!(lurker.line(), "", "the lurker should be closed");
    assert!(third.ask("VOXOCT-TT/1").starts_with("ERR BUSY "));
    // Shutdown with a session open returns promptly.
    let start = Instant::now();
    server.shutdown();
    assert!(
        start.elapsed() < Duration::from_secs(2),
        "{:?}",
        start.elapsed()
    );
    assert!(session.ping().is_err());
    assert!(TcpStream::connect_timeout(&addr, Duration::from_millis(500)).is_err());
}

/// A table whose every turn panics (as `--sim-speed 1e-20` once did).
struct Panicking;

impl Turntable for Panicking {
    fn rotate_by(&mut self, _: f64, _: Duration) -> Result<f64, TurntableError> {
        panic!("cannot convert float seconds to Duration");
    }
    fn angle_deg(&mut self) -> Result<f64, TurntableError> {
        Ok(0.0)
    }
    fn home(&mut self) -> Result<(), TurntableError> {
        Ok(())
    }
}

#[test]
fn d12_a_panicking_request_gets_an_err_reply_and_releases_its_slot() {
    let listener = TcpListener::bind("127.0.0.1:0").unwrap();
    let cfg = ServerConfig {
        max_connections: 8,
        ..config(None)
    };
    let server = serve(listener, Panicking, cfg).unwrap();
    // More clients than slots, one after the other: each gets an ERR reply, none BUSY.
    for k in 0..12 {
        let mut c = Raw::connect(server.local_addr());
        let hello = c.ask("VOXOCT-TT/1");
        assert!(hello.starts_with("OK "), "client {k}: {hello:?}");
        let reply = c.ask("ROTATE 1");
        assert!(reply.starts_with("ERR INTERNAL "), "client {k}: {reply:?}");
        assert!(c.ask("QUIT").starts_with("OK BYE"), "client {k}");
    }
    server.shutdown();
}

#[test]
fn d13_idle_connections_cannot_lock_out_a_client_with_the_token() {
    let listener = TcpListener::bind("127.0.0.1:0").unwrap();
    let cfg = ServerConfig {
        max_connections: 8,
        handshake_timeout: Duration::from_secs(30),
        ..config(Some("s3cret"))
    };
    let server = serve(listener, SimulatedTurntable::default(), cfg).unwrap();
    let addr = server.local_addr();
    for round in 0..5 {
        // Eight sockets that never send a handshake fill every slot…
        let idle: Vec<TcpStream> = (0..8).map(|_| TcpStream::connect(addr).unwrap()).collect();
        thread::sleep(Duration::from_millis(50));
        // …and the client with the token still gets in at once.
        let start = Instant::now();
        let mut c = RemoteTurntable::connect(addr, Some("s3cret"), quick())
            .unwrap_or_else(|e| panic!("round {round}: {e}"));
        assert_eq!(c.rotate_by(90.0, T).unwrap(), 90.0);
        assert!(
            start.elapsed() < Duration::from_secs(2),
            "{:?}",
            start.elapsed()
        );
        drop(c);
        drop(idle);
    }
    server.shutdown();
}

#[test]
fn d12_nonsensical_simulated_speeds_are_refused() {
    for speed in [1e-20, 0.0, -1.0, f64::NAN, f64::INFINITY, 1e300] {
        assert!(
            SimulatedTurntable::default().with_speed(speed).is_err(),
            "{speed}"
        );
    }
}

#[test]
fn d17_a_turn_refused_up_front_says_so_on_the_wire() {
    let table = SimulatedTurntable::default().with_speed(90.0).unwrap();
    let server = start(table, None);
    let mut c = Raw::connect(server.local_addr());
    assert!(c.ask("VOXOCT-TT/1").starts_with("OK "));
    let reply = c.ask("ROTATE 90 100");
    assert!(reply.starts_with("ERR TIMEOUT "), "{reply:?}");
    assert!(reply.contains("refused before moving"), "{reply:?}");
    server.shutdown();
}

#[test]
fn a_session_closed_for_idleness_reconnects_transparently() {
    let listener = TcpListener::bind("127.0.0.1:0").unwrap();
    let cfg = ServerConfig {
        idle_timeout: Duration::from_millis(200),
        ..config(None)
    };
    let server = serve(listener, SimulatedTurntable::default(), cfg).unwrap();
    let mut c = RemoteTurntable::connect(server.local_addr(), None, quick()).unwrap();
    assert_eq!(c.rotate_by(90.0, T).unwrap(), 90.0);
    // The server closes the idle session (after an unsolicited ERR TIMEOUT).
    thread::sleep(Duration::from_millis(700));
    // The next turn is not mistaken for that error: it reconnects first.
    assert_eq!(c.rotate_by(90.0, T).unwrap(), 90.0);
    assert_eq!(c.angle_deg().unwrap(), 180.0);
    server.shutdown();
}

mod fuzz {
    use super::*;
    use proptest::prelude::*;

    proptest! {
        #![proptest_config(ProptestConfig::with_cases(8))]
        /// Arbitrary request lines: each gets exactly one reply line or a
        /// clean close, and the server then serves a fresh client.
        #[test]
        fn junk_lines_never_break_the_server(
            lines in proptest::collection::vec(proptest::collection::vec(any::<u8>(), 0..300), 1..12)
        ) {
            let server = start(SimulatedTurntable::default(), None);
            let mut c = Raw::connect(server.local_addr());
            prop_assert_eq!(c.ask("VOXOCT-TT/1"), "OK VOXOCT-TT/1\n");
            for mut l in lines {
                l.retain(|&b| b != b'\n');
                // Keep QUIT out so the session goes on.
                if l.starts_with(b"QUIT") {
                    continue;
                }
                l.push(b'\n');
                c.send(&l);
                let reply = c.line();
                if l.len() > MAX_LINE_LEN {
                    prop_assert!(reply.starts_with("ERR TOO_LONG "));
                    c.assert_closed();
                    break;
                }
                prop_assert!(reply.starts_with("OK ") || reply.starts_with("ERR "), "{:?}", reply);
                prop_assert!(reply.ends_with('\n'));
            }
            drop(c);
            let mut fresh = connect_retry(server.local_addr(), None, T);
            fresh.ping().unwrap();
            server.shutdown();
        }
    }
}
