//! `config-tool panel` without a browser: a second panel on the same port is refused
//! with a clear error; a node that stops answering and a medium that goes away are said
//! in the page's state (its server-sent events) and the buttons refused, by the server
//! too; a panel off loopback needs its token; CONFIRM releases the node a confirmed trial
//! left without a role; nothing hangs.

mod e2e_support;
mod panel_support;

use panel_support::{panel_on, text_of, Machine, Panel, ROBOT};

fn buttons_enabled(state: &serde_json::Value) -> Vec<String> {
    let b = state["buttons"].as_object().expect("buttons");
    b.iter()
        .filter(|(_, v)| v["enabled"] == true)
        .map(|(k, _)| k.clone())
        .collect()
}

#[test]
fn a_second_panel_on_the_same_port_is_refused_with_a_clear_error() {
    let (dir, medium, first) = panel_on("panel-port", "127.0.0.1:0");
    let (k, m) = (dir.0.join("machine.key"), medium.addr().to_string());
    let k = k.to_str().unwrap();
    let port = first.addr.to_string();
    let second = Panel::start(&[ROBOT, "--keys", k, "--medium", &m, "--listen", &port]);
    let Err((status, err)) = second else {
        panic!("a second panel on {port} started");
    };
    assert_eq!(
        (status, err),
        (
            Some(1),
            format!(
                "error: cannot listen on {port}: the address is in use (another panel, or \
                 another program, listens there): give another --listen\n"
            )
        )
    );
    // The first one still serves.
    assert_eq!(first.get("/").0, 200);
}

#[test]
fn a_silent_node_and_a_medium_gone_are_said_and_every_command_refused() {
    let mut m = Machine::up("panel-bad", None);
    let panel = m.panel();
    let mut events = panel.events();
    events.until("HOME offered", |s| buttons_enabled(s) == ["HOME"]);
    // What the page greys out the server refuses too, with the same reason.
    assert_eq!(
        panel.press("START"),
        (409, "refused: not homed: HOME first".to_string())
    );
    assert_eq!(panel.press("JUMP"), (404, "no button JUMP".to_string()));
    m.bed.kill_node(0x0012);
    let s = events.until("GR not answering", |s| s["nodes"][1]["answering"] == false);
    assert_eq!(buttons_enabled(&s), Vec::<String>::new());
    assert_eq!(
        s["buttons"]["HOME"]["why"],
        "node 0x0012 (GR) does not answer"
    );
    assert_eq!(
        panel.press("HOME"),
        (409, "refused: node 0x0012 (GR) does not answer".to_string())
    );
    m.bed.medium().stop();
    let s = events.until("the medium gone", |s| s["medium_ok"] == false);
    assert_eq!(s["medium"], "the medium closed");
    assert_eq!(
        panel.press("HOME"),
        (409, "refused: no medium: the medium closed".to_string())
    );
    // The page is still served.
    assert_eq!(panel.get("/").0, 200);
    assert_eq!(panel.get("/nothing").0, 404);
}

/// Sends `bytes` to the panel at `at` and reads the answer's status line (empty if the
/// connection closed without one).
fn status_of(at: std::net::SocketAddr, bytes: &[u8]) -> String {
    use std::io::{BufRead, Write};
    let mut s = std::net::TcpStream::connect(at).expect("connects");
    s.set_read_timeout(Some(e2e_support::TIMEOUT))
        .expect("timeout");
    s.write_all(bytes).expect("sends");
    let mut line = String::new();
    let _ = std::io::BufReader::new(s).read_line(&mut line);
    line.trim_end().to_string()
}

/// The head of the answer to `bytes` (status line and headers).
fn head_of(at: std::net::SocketAddr, bytes: &[u8]) -> String {
    use std::io::{BufRead, Write};
    let mut s = std::net::TcpStream::connect(at).expect("connects");
    s.set_read_timeout(Some(e2e_support::TIMEOUT))
        .expect("timeout");
    s.write_all(bytes).expect("sends");
    let mut r = std::io::BufReader::new(s);
    let mut head = String::new();
    loop {
        let mut line = String::new();
        if r.read_line(&mut line).unwrap_or(0) == 0 || line == "\r\n" {
            return head;
        }
        head.push_str(&line);
    }
}

/// What another site, a client too big or too many clients send is refused with its
/// status, and the panel goes on serving: a button only from the panel's own page
/// (`X-Panel: button`), no request of another site's page (a foreign `Origin`: an event
/// stream would hold one of the few slots), only requests for the panel's own address
/// (no other name resolved to it), a body of 10^12 bytes announced, a header of 100 KB;
/// and with every connection taken, one more is answered 503, and served again once
/// they close.
#[test]
fn requests_from_elsewhere_or_past_the_bounds_are_refused_and_the_panel_goes_on() {
    let (_dir, _medium, panel) = panel_on("panel-bounds", "127.0.0.1:0");
    let at = panel.addr;
    let post = |headers: &str| {
        panel_support::request_with(at, "POST", "/command/HOME", Some(""), headers).0
    };
    assert_eq!(post(""), 403, "no X-Panel: a form or fetch of another site");
    let foreign = "X-Panel: button\r\nOrigin: http://evil.example\r\n";
    assert_eq!(post(foreign), 403, "a foreign origin");
    let own = format!("X-Panel: button\r\nOrigin: http://{at}\r\n");
    assert_eq!(
        post(&own),
        409,
        "the page's own press: refused by the machine's state"
    );
    let stream =
        format!("GET /events HTTP/1.1\r\nHost: {at}\r\nOrigin: http://evil.example\r\n\r\n");
    assert_eq!(
        status_of(at, stream.as_bytes()),
        "HTTP/1.1 403 Forbidden",
        "another site's stream"
    );
    let rebound = format!(
        "GET /state.json HTTP/1.1\r\nHost: evil.example:{}\r\n\r\n",
        at.port()
    );
    assert_eq!(status_of(at, rebound.as_bytes()), "HTTP/1.1 403 Forbidden");
    let huge = format!(
        "POST /command/STOP HTTP/1.1\r\nHost: {at}\r\nContent-Length: 1000000000000\r\n\r\nx"
    );
    assert_eq!(
        status_of(at, huge.as_bytes()),
        "HTTP/1.1 413 Content Too Large"
    );
    let header = format!(
        "GET / HTTP/1.1\r\nHost: {at}\r\nX: {}\r\n\r\n",
        "a".repeat(100_000)
    );
    assert_eq!(
        status_of(at, header.as_bytes()),
        "HTTP/1.1 431 Request Header Fields Too Large"
    );
    assert_eq!(panel.get("/state.json").0, 200);
    // Every connection taken by a client that says nothing: the oldest are closed as
    // newer ones come (past MAX_HEADS: they answered 503 until the heads' deadline), and
    // the page is served while they are held, once the closed ones' threads are gone.
    let idle: Vec<std::net::TcpStream> = (0..robot_panel::server::MAX_CONNECTIONS)
        .map(|_| std::net::TcpStream::connect(at).expect("connects"))
        .collect();
    let get = format!("GET /state.json HTTP/1.1\r\nHost: {at}\r\n\r\n");
    let until = std::time::Instant::now() + e2e_support::TIMEOUT;
    while status_of(at, get.as_bytes()) != "HTTP/1.1 200 OK" {
        assert!(
            std::time::Instant::now() < until,
            "served while they are held"
        );
    }
    drop(idle);
}

/// Event streams that never read (a stuck tab, a local process holding connections) do
/// not keep a page out: a newcomer past the bound closes the oldest stream (a page's
/// `EventSource` opens another by itself). Issue: one more page was answered 503 for as
/// long as they stayed.
#[test]
fn streams_that_never_read_do_not_keep_a_page_out() {
    use std::io::{BufRead, BufReader, Read, Write};
    let (_dir, _medium, panel) = panel_on("panel-streams", "127.0.0.1:0");
    let at = panel.addr;
    // A stream opened, up to its answer's status line (its slot taken by then).
    let open = || {
        let mut s = std::net::TcpStream::connect(at).expect("connects");
        s.set_read_timeout(Some(e2e_support::TIMEOUT))
            .expect("timeout");
        s.write_all(format!("GET /events HTTP/1.1\r\nHost: {at}\r\n\r\n").as_bytes())
            .expect("sends");
        let mut r = BufReader::new(s);
        let mut line = String::new();
        r.read_line(&mut line).expect("reads");
        (line, r)
    };
    let held: Vec<_> = (0..robot_panel::streams::MAX_STREAMS)
        .map(|_| open())
        .collect();
    assert!(held.iter().all(|(l, _)| l == "HTTP/1.1 200 OK\r\n"));
    let (line, mut newcomer) = open();
    assert_eq!(line, "HTTP/1.1 200 OK\r\n");
    let state = loop {
        let mut line = String::new();
        newcomer.read_line(&mut line).expect("reads");
        if let Some(data) = line.strip_prefix("data: ") {
            break data.to_string();
        }
    };
    assert!(state.starts_with('{'), "{state}");
    // The oldest stream is closed: its reader comes to the end.
    let (_, mut oldest) = held.into_iter().next().expect("the oldest");
    let mut rest = Vec::new();
    oldest
        .read_to_end(&mut rest)
        .expect("the end, not a timeout");
}

#[test]
fn a_panel_off_loopback_prints_a_token_and_refuses_requests_without_it() {
    let (_dir, _medium, panel) = panel_on("panel-token", "0.0.0.0:0");
    let (_, token) = panel
        .url
        .split_once("?token=")
        .expect("a token in the address");
    assert_eq!(token.len(), 32);
    let at: std::net::SocketAddr = ([127, 0, 0, 1], panel.addr.port()).into();
    let get = |p: &str| panel_support::request(at, "GET", p, None).0;
    assert_eq!(get("/"), 403);
    assert_eq!(get("/state.json"), 403);
    assert_eq!(get("/state.json?token=wrong"), 403);
    assert_eq!(get(&format!("/state.json?token={token}")), 200);
    assert_eq!(
        panel_support::request(at, "POST", "/command/HOME", Some("")).0,
        403
    );
    // The page's address with the token leads to the page without it, the token kept in
    // a cookie of this panel's port (the address bar, the history and any `Referer`
    // carry no token), which then opens everything; no answer sends a `Referer` on.
    let port = panel.addr.port();
    let request = |target: &str, cookie: &str| {
        format!("GET {target} HTTP/1.1\r\nHost: {at}\r\n{cookie}Connection: close\r\n\r\n")
    };
    let head = head_of(at, request(&format!("/?token={token}"), "").as_bytes());
    assert!(head.starts_with("HTTP/1.1 303 See Other\r\n"), "{head}");
    assert!(head.contains("\r\nLocation: /\r\n"), "{head}");
    assert!(
        head.contains(&format!(
            "\r\nSet-Cookie: panel_token_{port}={token}; HttpOnly; SameSite=Strict; Path=/\r\n"
        )),
        "{head}"
    );
    for (cookie, status) in [
        (
            format!("Cookie: a=1; panel_token_{port}={token}\r\n"),
            "200 OK",
        ),
        (
            format!("Cookie: panel_token_{port}=wrong\r\n"),
            "403 Forbidden",
        ),
        (
            format!("Cookie: panel_token_{}={token}\r\n", port ^ 1),
            "403 Forbidden",
        ),
    ] {
        for target in ["/", "/state.json"] {
            let head = head_of(at, request(target, &cookie).as_bytes());
            assert!(
                head.starts_with(&format!("HTTP/1.1 {status}\r\n")),
                "{cookie} {target}: {head}"
            );
            assert!(
                head.contains("\r\nReferrer-Policy: no-referrer\r\n"),
                "{head}"
            );
        }
    }
}

#[test]
fn the_sorters_page_shows_each_ball_in_the_bin_it_landed_in() {
    let mut m = Machine::of("ball-sorter.ron", "panel-sorter", None);
    let c = e2e_support::robot("ball-sorter.ron", 1);
    let feed: Vec<String> = ["gray", "black", "orange", "black"]
        .map(String::from)
        .to_vec();
    let sim = robot_analysis::sorter::simulate(&c, Some(&feed)).expect("sim");
    let actuators = robot_net::live_plant::actuators(&c).expect("actuators");
    let balls = robot_net::live_feed::ball_feed(&c, &actuators, &feed).expect("feed");
    let landed = m.bed.set_plant_fed(actuators, balls).expect("fed plant");
    let panel = m.panel();
    let mut events = panel.events();
    let s = events.until("START offered", |s| {
        s["buttons"]["START"]["enabled"] == true
    });
    assert_eq!(
        s["station"]["at_sensors"], "gray",
        "the front ball lies at the sensors"
    );
    assert_eq!(panel.press("START").0, 200);
    // One feed: START is not pressed again at its end.
    assert_eq!(panel.press("STOP").0, 200);
    let mut want = vec![Vec::<String>::new(); 3];
    for (colour, b) in feed.iter().zip(&sim.balls) {
        let bin = b.bin.expect("sim lands every ball");
        want[bin - 1].push(colour.clone());
        landed
            .recv_timeout(e2e_support::TIMEOUT)
            .expect("a ball lands");
    }
    // The radio's events are opened with the machine's keys: the last ball's landing is
    // told (published by the sensing node after its bin's sensor pulsed).
    let told = |s: &serde_json::Value| {
        (s["events"].as_array().unwrap().iter())
            .any(|e| e["role"] == "SENSING" && e["event"] == "bins.landed")
    };
    let s = events.until("every ball in its bin, the landing told", |s| {
        s["station"]["bins"] == serde_json::json!(want) && told(s)
    });
    assert_eq!(s["station"]["falling"], 0);
    assert!(s["event_count"].as_u64().unwrap() >= 4 * 3, "{s:#}");
}

#[test]
fn the_transports_page_shows_each_control_functions_place() {
    let m = Machine::of("waterjet-transport.ron", "panel-transport", None);
    let c = e2e_support::robot("waterjet-transport.ron", 1);
    let panel = m.panel();
    let model: serde_json::Value =
        serde_json::from_str(&panel.get("/model.json").1).expect("the model");
    let mut events = panel.events();
    // Booted with its tables: every function in its chart's initial place.
    let s = events.until("every node answering", |s| {
        (s["nodes"].as_array().unwrap().iter()).all(|n| n["answering"] == true)
    });
    let functions = model["functions"].as_array().expect("functions");
    assert_eq!(functions.len(), c.robot.functions.len());
    for f in functions {
        let (name, chart) = (f[0].as_str().unwrap(), f[1].as_u64().unwrap() as usize);
        let ch = &model["charts"][chart];
        let place = s["charts"][chart].as_u64().expect("a state") as usize;
        assert_eq!(ch["name"], name);
        assert_eq!(place, ch["initial"].as_u64().unwrap() as usize, "{name}");
    }
}

/// The TCP port process `pid` listens on (Linux): one of its sockets (`/proc/PID/fd`)
/// found listening in `/proc/net/tcp`. `None` while it has none (or no longer runs).
#[cfg(target_os = "linux")]
fn listening_port(pid: u32) -> Option<u16> {
    let inodes: Vec<String> = std::fs::read_dir(format!("/proc/{pid}/fd"))
        .ok()?
        .filter_map(|e| std::fs::read_link(e.ok()?.path()).ok())
        .filter_map(|l| {
            let l = l.to_string_lossy().into_owned();
            Some(l.strip_prefix("socket:[")?.strip_suffix(']')?.to_string())
        })
        .collect();
    let table = std::fs::read_to_string("/proc/net/tcp").ok()?;
    table.lines().skip(1).find_map(|line| {
        let f: Vec<&str> = line.split_whitespace().collect();
        // local address, state (0A: listening), inode
        let (local, state, inode) = (f.get(1)?, f.get(3)?, f.get(9)?);
        (*state == "0A" && inodes.iter().any(|i| i == inode))
            .then(|| u16::from_str_radix(local.split_once(':')?.1, 16).ok())
            .flatten()
    })
}

/// Issue: a panel whose standard output was closed (a pipe whose reader went away, as
/// `config-tool panel ... | head -1` leaves it) died of it (a panic on printing its
/// address). A panel is a server: it goes on serving.
#[test]
fn a_panel_whose_output_is_closed_goes_on_serving() {
    let (dir, medium) = panel_support::keyed_medium("panel-closed-output");
    let key = dir.0.join("machine.key");
    let (reader, writer) = std::io::pipe().expect("a pipe");
    drop(reader);
    let child = std::process::Command::new(env!("CARGO_BIN_EXE_config-tool"))
        .current_dir(panel_support::root())
        .args(["panel", ROBOT, "--keys", key.to_str().unwrap()])
        .args([
            "--medium",
            &medium.addr().to_string(),
            "--listen",
            "127.0.0.1:0",
        ])
        .env_remove("CONFIG_TOOL_KEYS")
        .stdin(std::process::Stdio::null())
        .stdout(writer)
        .stderr(std::process::Stdio::null())
        .spawn()
        .expect("runs");
    let mut child = panel_support::Killed(child);
    // Its port, once it listens (or nothing, if it ended).
    let until = std::time::Instant::now() + e2e_support::TIMEOUT;
    let port = loop {
        if let Some(port) = listening_port(child.0.id()) {
            break port;
        }
        let ended = child.0.try_wait().expect("waits");
        assert!(
            ended.is_none() && std::time::Instant::now() < until,
            "ended: {ended:?}"
        );
    };
    // It prints its address, then asks the nodes how they are: its first question on the
    // medium comes after the print.
    while medium.stats().frames == 0 {
        let ended = child.0.try_wait().expect("waits");
        assert!(
            ended.is_none() && std::time::Instant::now() < until,
            "ended: {ended:?}"
        );
    }
    let at: std::net::SocketAddr = ([127, 0, 0, 1], port).into();
    assert_eq!(
        panel_support::request(at, "GET", "/state.json", None).0,
        200
    );
    assert_eq!(child.0.try_wait().expect("waits"), None, "still serving");
}

/// The panel's CONFIRM of a trial that moved VC to the spare node releases the node VC
/// left (as `config-tool confirm` does: a rollback before it finds the machine as it was),
/// and says so in its answer.
#[test]
fn the_panels_confirm_releases_the_node_a_confirmed_trial_left_without_a_role() {
    let mut m = Machine::up("panel-confirm", None);
    m.bed.start_node(0x0015).expect("the spare's process");
    m.bed
        .wait_for_nodes(&[0x0015])
        .expect("the spare announces itself");
    let homed = m.tool(&["home", &m.robot]);
    assert!(homed.status.success(), "{}", text_of(&homed.stderr));
    let moved = "robot-configs/paint-robot-spare-node.ron";
    let trial = m.tool(&["push", moved, "--generation", "2", "--trial"]);
    assert!(trial.status.success(), "{}", text_of(&trial.stderr));
    let key = m.key.to_str().expect("utf-8 path").to_string();
    let medium = m.medium();
    let panel = Panel::start(&[
        moved,
        "--keys",
        &key,
        "--medium",
        &medium,
        "--listen",
        "127.0.0.1:0",
    ])
    .expect("the panel starts");
    let mut events = panel.events();
    events.until("CONFIRM offered", |s| {
        s["buttons"]["CONFIRM"]["enabled"] == true
    });
    assert_eq!(
        panel.press("CONFIRM"),
        (
            200,
            "generation 2 confirmed on 4 of 4 node(s); node 0x0011 (node-1) plays no role \
             in this robot: released (it ran VC of generation 1; now no table runs there, \
             its outputs are off)"
                .to_string()
        )
    );
    drop(events);
    drop(panel);
    let scan = m.tool(&["scan", moved]);
    assert!(
        text_of(&scan.stdout).contains("0x0011  firmware 1  generation 2  (no role)\n"),
        "{}{}",
        text_of(&scan.stdout),
        text_of(&scan.stderr)
    );
}
