//! The operator's panel (docs/panel.md), measured against issue 17's target: a pin change
//! on the page within 100 ms. The paint robot runs on this host (medium, one
//! `config-tool node` process per node, the plant); the panel runs in this process on it
//! (its feed, its radio, its server), HOME and START pressed through its buttons. For
//! every pin change the medium stamps (a valve a node drives, a switch the plant sets)
//! during a few cycles:
//! - panel: from the medium's stamp to the first server-sent event carrying it (its
//!   `pin_us`) read by a plain HTTP client over TCP;
//! - baseline, the same run: from the same stamp to a plain monitor on the medium seeing
//!   it (the host's scheduling and TCP show in both).
//!
//! `cargo bench -p config-tool --bench panel`

mod support;
use support::{bed_of, paint_robot};

use std::io::{BufRead, BufReader, Read, Write};
use std::net::{SocketAddr, TcpStream};
use std::sync::mpsc;
use std::sync::{Arc, Mutex};
use std::time::{Duration, Instant};

use config_schema::wire::medium::{Link, Peer};
use medium::Conn;
use robot_net::radio::{ToolRadio, TOOL_ADDR};
use robot_panel::{Listener, Panel};

/// The cycles measured.
const CYCLES: u32 = 4;
/// The target of issue 17.
const TARGET_MS: f64 = 100.0;
/// Any wait here.
const WAIT: Duration = Duration::from_secs(60);

/// One HTTP/1.1 POST with an empty body (`Connection: close`), as the page presses a
/// button: the status and the body.
fn post(addr: SocketAddr, path: &str) -> (u16, String) {
    let mut s = TcpStream::connect_timeout(&addr, WAIT).expect("connects");
    s.set_read_timeout(Some(Duration::from_secs(180)))
        .expect("timeout");
    write!(
        s,
        "POST {path} HTTP/1.1\r\nHost: {addr}\r\nConnection: close\r\nX-Panel: button\r\n\
         Content-Length: 0\r\n\r\n"
    )
    .expect("sends");
    let mut answer = String::new();
    s.read_to_string(&mut answer).expect("an answer");
    let status = (answer.split(' ').nth(1))
        .and_then(|c| c.parse().ok())
        .unwrap_or(0);
    let body = answer
        .split_once("\r\n\r\n")
        .map_or("", |x| x.1)
        .to_string();
    (status, body)
}

/// What the page's client read: each state's arrival and the fields the bench follows.
struct Seen {
    at: Instant,
    pin_us: Option<u64>,
    cycles: u64,
    start_enabled: bool,
    home_enabled: bool,
}

/// Reads the panel's server-sent events until the stream ends, each state stamped as
/// its line is read (before it is parsed).
fn read_events(addr: SocketAddr, out: mpsc::Sender<Seen>) {
    let mut s = TcpStream::connect_timeout(&addr, WAIT).expect("connects");
    write!(s, "GET /events HTTP/1.1\r\nHost: {addr}\r\n\r\n").expect("sends");
    let mut r = BufReader::new(s);
    let mut line = String::new();
    loop {
        line.clear();
        match r.read_line(&mut line) {
            Ok(0) | Err(_) => return,
            Ok(_) => {}
        }
        let at = Instant::now();
        let Some(data) = line.strip_prefix("data: ") else {
            continue;
        };
        let v: serde_json::Value = serde_json::from_str(data).expect("a state");
        let seen = Seen {
            at,
            pin_us: v["pin_us"].as_u64(),
            cycles: v["cycles"].as_u64().unwrap_or(0),
            start_enabled: v["buttons"]["START"]["enabled"].as_bool() == Some(true),
            home_enabled: v["buttons"]["HOME"]["enabled"].as_bool() == Some(true),
        };
        if out.send(seen).is_err() {
            return;
        }
    }
}

fn percentile(sorted: &[f64], p: f64) -> f64 {
    let i = ((sorted.len() as f64 - 1.0) * p).round() as usize;
    sorted.get(i).copied().unwrap_or(f64::NAN)
}

fn line(name: &str, v: &mut [f64]) -> String {
    v.sort_by(|a, b| a.total_cmp(b));
    format!(
        "  {name:<34} median {:>6.2} ms   p90 {:>6.2} ms   max {:>6.2} ms",
        percentile(v, 0.5),
        percentile(v, 0.9),
        v.last().copied().unwrap_or(f64::NAN)
    )
}

fn main() {
    let c = paint_robot();
    let (mut bed, _) = bed_of(&c, WAIT);
    bed.push(&c, false, &mut |_, _, _| {}).expect("push");
    let medium_at = bed.medium().addr();
    let zero = bed.medium().started();

    // The panel, with its own radio (made on the thread that runs it), secured with the
    // bed's secret; its counter far above the bed radio's (which is not used again).
    let secret = bed.secret().expect("a secured bed").clone();
    let listener = Listener::bind("127.0.0.1:0".parse().expect("address")).expect("listens");
    let panel = Panel::start(listener, c.clone(), medium_at, Some(secret.clone())).expect("panel");
    let addr = panel.addr();
    std::thread::spawn(move || {
        let mut radio = ToolRadio::connect(medium_at, TOOL_ADDR).expect("the panel's radio");
        let mut next = 1u32 << 24;
        radio.secure(
            secret,
            Box::new(move || {
                next = (next.checked_add(1)).ok_or_else(|| std::io::Error::other("used up"))?;
                Ok(next)
            }),
        );
        panel.serve(radio)
    });

    // The baseline: a plain monitor, every stamped pin change and when it arrived.
    let pins: Arc<Mutex<Vec<(u64, Instant)>>> = Arc::default();
    let mut monitor = Conn::join(medium_at, Peer::Monitor).expect("monitor");
    let heard = pins.clone();
    std::thread::spawn(move || {
        let far = Instant::now() + Duration::from_secs(24 * 3600);
        // The levels as last seen: a stamp that repeats one is no change.
        let mut levels = std::collections::BTreeMap::new();
        let _ = monitor.recv(far, |l| {
            if let Link::Seen {
                at_us,
                addr,
                pin,
                level,
                output,
            } = l
            {
                let now = Instant::now();
                if levels.insert((addr, pin, output), level) != Some(level) {
                    heard.lock().expect("pins").push((at_us, now));
                }
            }
            None::<()>
        });
    });
    let (tx, states) = mpsc::channel();
    std::thread::spawn(move || read_events(addr, tx));
    let next_state = |until: Instant| {
        states
            .recv_timeout(until.saturating_duration_since(Instant::now()))
            .expect("the panel's events")
    };

    let until = Instant::now() + WAIT;
    while !next_state(until).home_enabled {}
    let (code, said) = post(addr, "/command/HOME");
    assert_eq!(code, 200, "HOME: {said}");
    let until = Instant::now() + WAIT;
    while !next_state(until).start_enabled {}
    // Only the cycles' pin changes are counted (from START on).
    let from_us = zero.elapsed().as_micros() as u64;
    let (code, said) = post(addr, "/command/START");
    assert_eq!(code, 200, "START: {said}");
    let mut got = Vec::new();
    let until = Instant::now() + WAIT * CYCLES;
    loop {
        let s = next_state(until);
        let done = s.cycles >= u64::from(CYCLES);
        got.push(s);
        if done {
            break;
        }
    }
    let (code, said) = post(addr, "/command/STOP");
    assert_eq!(code, 200, "STOP: {said}");
    // Whatever the page still gets of the last pin change.
    let until = Instant::now() + Duration::from_millis(500);
    while let Ok(s) = states.recv_timeout(until.saturating_duration_since(Instant::now())) {
        got.push(s);
    }

    let changes: Vec<(u64, Instant)> = pins
        .lock()
        .expect("pins")
        .iter()
        .filter(|(at_us, _)| *at_us >= from_us)
        .copied()
        .collect();
    let last_us = got.iter().filter_map(|s| s.pin_us).max().unwrap_or(0);
    let mut page = Vec::new();
    let mut monitor = Vec::new();
    for (at_us, monitor_at) in changes.iter().filter(|(at, _)| *at <= last_us) {
        let stamped = zero + Duration::from_micros(*at_us);
        // Every state carries the pin changes up to its `pin_us`: the first that reaches
        // this one's stamp brought it to the page.
        let Some(s) = got.iter().find(|s| s.pin_us.is_some_and(|p| p >= *at_us)) else {
            continue;
        };
        page.push(s.at.saturating_duration_since(stamped).as_secs_f64() * 1e3);
        monitor.push(monitor_at.saturating_duration_since(stamped).as_secs_f64() * 1e3);
    }
    assert!(!page.is_empty(), "no pin change reached the page");
    let states_seen = got.iter().filter(|s| s.pin_us >= Some(from_us)).count();
    let over = page.iter().filter(|ms| **ms >= TARGET_MS).count();
    println!(
        "panel latency over {CYCLES} cycles of the paint robot: {} pin changes, {states_seen} \
         server-sent states",
        page.len()
    );
    println!("{}", line("pin change -> page's event stream", &mut page));
    println!("{}", line("baseline: pin change -> monitor", &mut monitor));
    println!(
        "  target: < {TARGET_MS:.0} ms from the pin change to the page: {}",
        match over {
            0 => "met by every pin change".to_string(),
            n => format!("NOT MET by {n} pin changes"),
        }
    );
    println!("  (path: medium -> the panel's monitor (feed thread) -> the live machine -> every stream woken -> the state written; no poll round on it)");
    bed.stop();
}
