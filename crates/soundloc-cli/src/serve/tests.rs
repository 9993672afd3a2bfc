//! The live view server's tests.

use super::*;

/// Pages that closed free their places though nothing is broadcast any more (after
/// the input ended): twice the cap of pages come and go, then the page loads. Before,
/// each closed page held its thread until the next broadcast, and all later requests
/// got 503.
#[test]
fn closed_pages_free_their_places_when_nothing_is_sent() {
    let v = LiveServer::bind("127.0.0.1:0", &[]).unwrap();
    v.hello("{\"type\":\"hello\"}".into());
    let addr = v.local_addr();
    for round in 0..2 {
        let pages: Vec<_> = (0..MAX_CLIENTS / 2 + 8)
            .map(|_| {
                let (mut ws, _) = tungstenite::connect(format!("ws://{addr}/ws")).unwrap();
                assert!(matches!(ws.read().unwrap(), Message::Text(_)), "hello");
                ws
            })
            .collect();
        let mut pages = pages;
        for ws in &mut pages {
            ws.close(None).unwrap();
        }
        // Each is answered (a close frame, then the end of the connection).
        for ws in &mut pages {
            while ws.read().is_ok() {}
        }
        page_loads_within(addr, Duration::from_secs(10), &format!("round {round}"));
    }
}

/// A head that is not UTF-8 and a /ws request without a key get a 400 at once.
#[test]
fn malformed_requests_get_400() {
    let v = LiveServer::bind("127.0.0.1:0", &[]).unwrap();
    for req in [
        &b"GET /\xff\xfe HTTP/1.1\r\nHost: 127.0.0.1\r\n\r\n"[..],
        b"GET /ws HTTP/1.1\r\nHost: 127.0.0.1\r\nUpgrade: websocket\r\nConnection: Upgrade\r\n\r\n",
    ] {
        let mut c = TcpStream::connect(v.local_addr()).unwrap();
        c.set_read_timeout(Some(Duration::from_secs(10))).unwrap();
        c.write_all(req).unwrap();
        let t = Instant::now();
        let mut got = String::new();
        let _ = c.read_to_string(&mut got);
        assert!(got.starts_with("HTTP/1.1 400"), "{got:?}");
        assert!(t.elapsed() < Duration::from_secs(2), "answered at once");
    }
}

/// Idle connections beyond [`MAX_CLIENTS`] get a 503 at once instead of a thread each.
#[test]
fn connections_beyond_the_cap_are_refused() {
    let v = LiveServer::bind("127.0.0.1:0", &[]).unwrap();
    let idle: Vec<TcpStream> = (0..MAX_CLIENTS)
        .map(|_| TcpStream::connect(v.local_addr()).unwrap())
        .collect();
    let mut extra = TcpStream::connect(v.local_addr()).unwrap();
    extra.set_read_timeout(Some(Duration::from_secs(4))).unwrap();
    let mut got = String::new();
    let _ = extra.read_to_string(&mut got);
    assert!(got.starts_with("HTTP/1.1 503"), "{got:?}");
    // A served client that leaves frees its place.
    drop(idle);
    page_loads_within(
        v.local_addr(),
        Duration::from_secs(20),
        "after the idle clients left",
    );
}

/// GET / until it answers 200, failing after `limit`.
fn page_loads_within(addr: SocketAddr, limit: Duration, what: &str) {
    let t = Instant::now();
    loop {
        let mut c = TcpStream::connect(addr).unwrap();
        c.set_read_timeout(Some(Duration::from_secs(4))).unwrap();
        c.write_all(b"GET / HTTP/1.1\r\nHost: 127.0.0.1\r\n\r\n").unwrap();
        let mut page = String::new();
        let _ = c.read_to_string(&mut page);
        if page.starts_with("HTTP/1.1 200") {
            return;
        }
        assert!(t.elapsed() < limit, "{what}: {page:?}");
        std::thread::sleep(Duration::from_millis(100));
    }
}

/// Host names that reach this server: its addresses, localhost, its own name, the names
/// given with --serve-host; any other (a rebinding page's) is refused.
#[test]
fn host_names_of_this_server_and_others() {
    let extra = server_names(&["ROBOT.example.".to_string()]);
    for h in [
        "127.0.0.1:8080",
        "192.168.1.20",
        "[::1]:8080",
        "localhost:8080",
        "LocalHost",
        "view.localhost:1",
        "robot.example:8080",
        "ROBOT.example.",
    ] {
        assert!(host_allowed(h, &extra), "{h}");
    }
    for h in [
        "attacker.example:8080",
        "evil.com",
        "[nonsense]:1",
        "127.0.0.1.evil.com",
    ] {
        assert!(!host_allowed(h, &extra), "{h}");
    }
    let me = own_name();
    if !me.is_empty() {
        assert!(host_allowed(&format!("{me}:80"), &server_names(&[])));
        assert!(host_allowed(&format!("{me}.local"), &server_names(&[])));
        assert!(!host_allowed(&format!("{me}:80"), &[]));
    }
}

/// A rebinding page (its own name in Host, its own origin) gets neither the page nor the
/// stream; the same requests under the server's address get both.
#[test]
fn a_foreign_host_gets_403_for_the_page_and_the_stream() {
    let v = LiveServer::bind("127.0.0.1:0", &[]).unwrap();
    v.hello("{\"type\":\"hello\"}".into());
    let addr = v.local_addr();
    let ask = |host: &str, ws: bool| {
        let mut c = TcpStream::connect(addr).unwrap();
        let req = if ws {
            format!(
                "GET /ws HTTP/1.1\r\nHost: {host}\r\nOrigin: http://{host}\r\nUpgrade: websocket\r\n\
                 Connection: Upgrade\r\nSec-WebSocket-Key: dGhlIHNhbXBsZSBub25jZQ==\r\nSec-WebSocket-Version: 13\r\n\r\n"
            )
        } else {
            format!("GET / HTTP/1.1\r\nHost: {host}\r\n\r\n")
        };
        c.write_all(req.as_bytes()).unwrap();
        // A plain answer ends with the connection; an open stream, at the timeout.
        c.set_read_timeout(Some(Duration::from_secs(1))).unwrap();
        let mut got = Vec::new();
        let _ = c.read_to_end(&mut got);
        String::from_utf8_lossy(&got).into_owned()
    };
    let evil = "attacker.example:8080";
    for ws in [false, true] {
        let got = ask(evil, ws);
        assert!(
            got.starts_with("HTTP/1.1 403") && got.contains("--serve-host attacker.example"),
            "{got}"
        );
    }
    assert!(ask(&addr.to_string(), false).starts_with("HTTP/1.1 200"));
    assert!(ask(&addr.to_string(), true).starts_with("HTTP/1.1 101"));
}
