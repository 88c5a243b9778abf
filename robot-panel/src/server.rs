//! The panel's HTTP server (a thread per connection, at most [`MAX_CONNECTIONS`], one
//! request each: [`crate::http`]): the page and its two scripts' worth of files (embedded,
//! nothing fetched from elsewhere), `model.json`, `state.json`, `events` (server-sent
//! events: the state again at every change) and `POST command/NAME`. Off loopback every
//! request must carry the token printed at start-up: in its address (`?token=`: the
//! printed address, whose page answers with the page's own address and the token in an
//! `HttpOnly`, `SameSite=Strict` cookie of the panel's port) or in that cookie (the page's
//! own requests); no answer lets a `Referer` carry an address on. On loopback a request
//! must name the panel's own address as its `Host` (no other site's name resolved to
//! it). A request's `Origin`, if any, must be the panel's own (a page of another site
//! opens no event stream), and a button's POST must carry `X-Panel: button`, which no
//! page of another origin can send without the panel's consent (it gives none).

use std::io::{self, Write};
use std::net::{IpAddr, Ipv4Addr, Ipv6Addr, SocketAddr, TcpListener, TcpStream};
use std::sync::atomic::{AtomicBool, AtomicUsize, Ordering};
use std::sync::mpsc::{self, Receiver, SyncSender, TrySendError};
use std::sync::{Arc, Mutex};
use std::thread::JoinHandle;
use std::time::Duration;

use crate::buttons::{self, Button};
use crate::error::PanelError;
use crate::http::{self, Refused, Request};
use crate::live::Live;
use crate::model::Machine;
use crate::poll::{self, Claim, Order};
use crate::shared::Shared;
use crate::streams::{Streams, MAX_HEADS, MAX_STREAMS};
use crate::{feed, view};
use robot_compiler::compile::Compiled;
use robot_keys::MachineSecret;
use robot_net::radio::ToolRadio;

const INDEX: &str = include_str!("page/index.html");
const SCRIPT: &str = include_str!("page/panel.js");
const STYLE: &str = include_str!("page/panel.css");

/// At most this many other requests are served at once (each holds a thread).
const MAX_REQUESTS: usize = 64;
/// At most this many connections at once (each holds a thread): more are answered 503
/// and closed.
pub const MAX_CONNECTIONS: usize = MAX_REQUESTS + MAX_STREAMS;
/// A stream with no change says something this often (a page that went away is found).
const KEEPALIVE: Duration = Duration::from_secs(5);
/// The longest an order may take (homing waits for the machine).
const ORDER_WITHIN: Duration = Duration::from_secs(120);
/// At most this many orders wait for the radio thread (more are answered 503).
const MAX_ORDERS: usize = 8;

/// The panel's socket, bound before anything else is opened: a second panel on the same
/// port is refused first, with a clear error.
pub struct Listener {
    listener: TcpListener,
    addr: SocketAddr,
}

impl Listener {
    pub fn bind(addr: SocketAddr) -> Result<Listener, PanelError> {
        let listener = TcpListener::bind(addr).map_err(|source| match source.kind() {
            io::ErrorKind::AddrInUse => PanelError::InUse { addr },
            _ => PanelError::Listen { addr, source },
        })?;
        let addr = listener
            .local_addr()
            .map_err(|source| PanelError::Listen { addr, source })?;
        // Each server-sent event is one small write, often while the page has not yet
        // acknowledged the one before: with Nagle's algorithm it would wait for that
        // acknowledgement (the page's delayed ACK, 40 ms on Linux). The connections
        // accepted inherit the option from the listener (Linux, the BSDs).
        socket2::SockRef::from(&listener)
            .set_tcp_nodelay(true)
            .map_err(|source| PanelError::Listen { addr, source })?;
        Ok(Listener { listener, addr })
    }

    pub fn addr(&self) -> SocketAddr {
        self.addr
    }
}

/// A running panel.
pub struct Panel {
    addr: SocketAddr,
    run: Option<Run>,
    token: Option<String>,
    stop: Arc<AtomicBool>,
    threads: Vec<JoinHandle<()>>,
}

/// What the radio loop takes when [`Panel::serve`] runs it.
struct Run {
    c: Arc<Compiled>,
    machine: Arc<Machine>,
    shared: Arc<Shared>,
    inbox: mpsc::Receiver<Order>,
}

struct Ctx {
    c: Arc<Compiled>,
    machine: Arc<Machine>,
    model: String,
    shared: Arc<Shared>,
    orders: Mutex<SyncSender<Order>>,
    token: Option<String>,
    /// The name of the cookie that keeps the token ([`cookie_name`]).
    cookie: String,
    /// The panel's own address, as a request's `Host` names it.
    addr: SocketAddr,
    streams: Streams,
    /// The requests whose head is being read.
    heads: Streams,
    connections: AtomicUsize,
    stop: Arc<AtomicBool>,
}

/// A fresh token: 16 random bytes, hex.
fn new_token() -> String {
    let bytes: [u8; 16] = rand::random();
    bytes.iter().map(|b| format!("{b:02x}")).collect()
}

impl Panel {
    /// Serves the page of `c` on `listener`, the pins and events from the medium at
    /// `medium` (secured events opened with `secret`); the
    /// nodes' answers and the buttons once [`Panel::serve`] runs the radio. A token is
    /// made when the listener is not on loopback.
    pub fn start(
        listener: Listener,
        c: Compiled,
        medium: SocketAddr,
        secret: Option<MachineSecret>,
    ) -> Result<Panel, PanelError> {
        let machine = Arc::new(Machine::of(&c)?);
        let model = serde_json::to_string(&*machine)
            .map_err(|e| PanelError::Robot(format!("the page model: {e}")))?;
        let c = Arc::new(c);
        let shared = Arc::new(Shared::new(Live::new(&machine)));
        let stop = Arc::new(AtomicBool::new(false));
        let token = (!listener.addr.ip().is_loopback()).then(new_token);
        let keys = (secret, c.ir.generation);
        let feed = feed::start(medium, machine.clone(), shared.clone(), keys, stop.clone())
            .map_err(|source| PanelError::Medium {
                addr: medium,
                source,
            })?;
        let (orders, inbox) = mpsc::sync_channel(MAX_ORDERS);
        let run = Run {
            c: c.clone(),
            machine: machine.clone(),
            shared: shared.clone(),
            inbox,
        };
        let addr = listener.addr;
        let ctx = Arc::new(Ctx {
            c,
            machine,
            model,
            shared,
            orders: Mutex::new(orders),
            token: token.clone(),
            cookie: cookie_name(addr),
            addr,
            streams: Streams::default(),
            heads: Streams::bounded(MAX_HEADS),
            connections: AtomicUsize::new(0),
            stop: stop.clone(),
        });
        let listener = listener.listener;
        let accept = std::thread::Builder::new()
            .name("panel-http".into())
            .spawn(move || accept_loop(&ctx, &listener))
            .map_err(PanelError::Thread)?;
        Ok(Panel {
            addr,
            run: Some(run),
            token,
            stop,
            threads: vec![feed, accept],
        })
    }

    pub fn addr(&self) -> SocketAddr {
        self.addr
    }

    /// The token a request must carry (`None`: on loopback, none needed).
    pub fn token(&self) -> Option<&str> {
        self.token.as_deref()
    }

    /// The page's address (with the token, if one is needed).
    pub fn url(&self) -> String {
        match &self.token {
            Some(t) => format!("http://{}/?token={t}", self.addr),
            None => format!("http://{}/", self.addr),
        }
    }

    /// Runs the tool's `radio` on this thread for the panel (asking the nodes, carrying
    /// out the buttons) until the panel is stopped or the medium goes away; then serves
    /// the page (saying so) until the process ends.
    pub fn serve(mut self, radio: ToolRadio) {
        if let Some(r) = self.run.take() {
            poll::run(r.c, r.machine, radio, r.shared, r.inbox, self.stop.clone());
        }
        while let Some(t) = self.threads.pop() {
            let _ = t.join();
        }
    }
}

impl Drop for Panel {
    fn drop(&mut self) {
        self.stop.store(true, Ordering::Relaxed);
        // Wakes the accept loop, which then sees the stop.
        let ip = match self.addr.ip() {
            IpAddr::V4(ip) if ip.is_unspecified() => IpAddr::V4(Ipv4Addr::LOCALHOST),
            IpAddr::V6(ip) if ip.is_unspecified() => IpAddr::V6(Ipv6Addr::LOCALHOST),
            ip => ip,
        };
        let _ = TcpStream::connect_timeout(&SocketAddr::new(ip, self.addr.port()), WAKE_WITHIN);
    }
}

/// How long dropping the panel waits to wake its accept loop.
const WAKE_WITHIN: Duration = Duration::from_secs(1);

/// Accepts connections until the panel stops, each served on a thread of its own, at
/// most [`MAX_CONNECTIONS`] at once. An accept that fails (no file descriptor left) is
/// tried again a little later: the listener stays.
fn accept_loop(ctx: &Arc<Ctx>, listener: &TcpListener) {
    for conn in listener.incoming() {
        if ctx.stop.load(Ordering::Relaxed) {
            return;
        }
        let mut stream = match conn {
            Ok(stream) => stream,
            Err(_) => {
                std::thread::sleep(Duration::from_millis(50));
                continue;
            }
        };
        let _ = stream.set_write_timeout(Some(http::WRITE_WITHIN));
        if ctx.connections.fetch_add(1, Ordering::SeqCst) >= MAX_CONNECTIONS {
            ctx.connections.fetch_sub(1, Ordering::SeqCst);
            // A fresh connection's send buffer takes this at once.
            let _ = http::respond(&mut stream, 503, "text/plain", "the panel is busy\n");
            continue;
        }
        let spawned = std::thread::Builder::new()
            .name("panel-request".into())
            .spawn({
                let ctx = ctx.clone();
                move || {
                    serve(&ctx, stream);
                    ctx.connections.fetch_sub(1, Ordering::SeqCst);
                }
            });
        if spawned.is_err() {
            ctx.connections.fetch_sub(1, Ordering::SeqCst);
        }
    }
}

/// The path and the query's token.
fn split(url: &str) -> (&str, Option<&str>) {
    let (path, query) = url.split_once('?').unwrap_or((url, ""));
    let token = query.split('&').find_map(|kv| kv.strip_prefix("token="));
    (path, token)
}

/// The name of the cookie that keeps the token of the panel at `addr` (cookies are not
/// kept apart by port: two panels on one host each have their own).
fn cookie_name(addr: SocketAddr) -> String {
    format!("panel_token_{}", addr.port())
}

/// The value of cookie `name` in a `Cookie` header.
fn cookie<'a>(header: Option<&'a str>, name: &str) -> Option<&'a str> {
    header?.split(';').find_map(|kv| {
        let (k, v) = kv.trim().split_once('=')?;
        (k == name).then_some(v)
    })
}

/// Whether `host` (a request's `Host`) names the panel at `addr`: its address, or on
/// loopback `localhost`, `127.0.0.1` or `[::1]`, with its port (none for port 80).
fn names_panel(host: Option<&str>, addr: SocketAddr) -> bool {
    let Some(host) = host else {
        return false;
    };
    let (name, port) = match host.strip_prefix('[').and_then(|h| h.split_once(']')) {
        Some((v6, rest)) => (format!("[{v6}]"), rest.strip_prefix(':')),
        None => match host.rsplit_once(':') {
            Some((name, port)) => (name.to_string(), Some(port)),
            None => (host.to_string(), None),
        },
    };
    let port = port.map_or(Some(80), |p| p.parse::<u16>().ok());
    let own = match addr.ip() {
        IpAddr::V4(ip) => ip.to_string(),
        IpAddr::V6(ip) => format!("[{ip}]"),
    };
    port == Some(addr.port())
        && (name == own || ["localhost", "127.0.0.1", "[::1]"].contains(&name.as_str()))
}

/// `a == b` in time that depends on their lengths only.
fn same(a: &str, b: &str) -> bool {
    a.len() == b.len() && a.bytes().zip(b.bytes()).fold(0u8, |d, (x, y)| d | (x ^ y)) == 0
}

/// Serves the one request of a connection.
fn serve(ctx: &Ctx, mut stream: TcpStream) {
    // Among the heads being read until it is read: a newcomer past MAX_HEADS closes the
    // oldest (a client that never finishes its heads holds no more connections than that).
    let reading = ctx.heads.open(&stream);
    let read = http::read(&mut stream);
    drop(reading);
    let rq = match read {
        Ok(rq) => rq,
        Err(Refused::Status(code, why)) => {
            let _ = http::respond(&mut stream, code, "text/plain", &format!("{why}\n"));
            return;
        }
        Err(Refused::Gone) => return,
    };
    let (code, kind, body) = match answer(ctx, &rq) {
        Answer::Page(code, kind, body) => (code, kind, body),
        Answer::Events => return stream_events(ctx, stream),
        Answer::Enter(token) => {
            // The page without the token in its address, the token in a cookie only this
            // site's own requests carry, out of reach of the page's scripts.
            let extra = format!(
                "Location: /\r\nSet-Cookie: {}={token}; HttpOnly; SameSite=Strict; Path=/\r\n",
                ctx.cookie
            );
            let _ = http::respond_with(&mut stream, 303, "text/plain", "", &extra);
            return;
        }
    };
    let _ = http::respond(&mut stream, code, kind, &body);
}

/// What a request is answered with.
enum Answer {
    Page(u16, &'static str, String),
    /// The server-sent events.
    Events,
    /// The page's address with this (right) token: on to the page, the token in a cookie.
    Enter(String),
}

fn answer(ctx: &Ctx, rq: &Request) -> Answer {
    let plain = "text/plain";
    let page = |code, kind, body: &str| Answer::Page(code, kind, body.to_string());
    let (path, token) = split(&rq.target);
    // The token in the address (the page's first load, a script's request) or in the
    // cookie the first load set.
    let kept = cookie(rq.header("cookie"), &ctx.cookie);
    let given = |t: &str| [token, kept].into_iter().flatten().any(|g| same(g, t));
    // The script and the style say nothing of the machine: fetched without the token.
    let open = matches!(path, "/panel.js" | "/panel.css");
    match &ctx.token {
        Some(t) if !open && !given(t) => {
            return page(
                403,
                plain,
                "this panel listens off loopback: open the address it printed at start-up, \
                 with its token\n",
            )
        }
        None if !names_panel(rq.header("host"), ctx.addr) => {
            return page(
                403,
                plain,
                "this panel answers requests for its own address only\n",
            )
        }
        _ => {}
    }
    // A page of another site may open connections to the panel (an event stream holds one
    // of its few slots): the browser says whose page it is.
    let own = rq.header("host").map(|h| format!("http://{h}"));
    // An `<img>`, `<script>` or frame of another site's page sends no `Origin`, but its
    // browser says the request is not the page's own (`Sec-Fetch-Site`).
    let foreign = rq
        .header("sec-fetch-site")
        .is_some_and(|s| s != "same-origin" && s != "none");
    if foreign
        || rq
            .header("origin")
            .is_some_and(|o| Some(o) != own.as_deref())
    {
        return page(403, plain, "this panel answers its own page only\n");
    }
    let json = "application/json";
    match (rq.method.as_str(), path) {
        ("GET", "/") => match (&ctx.token, token) {
            (Some(t), Some(g)) if same(g, t) => Answer::Enter(t.clone()),
            _ => page(200, "text/html; charset=utf-8", INDEX),
        },
        ("GET", "/panel.js") => page(200, "text/javascript", SCRIPT),
        ("GET", "/panel.css") => page(200, "text/css", STYLE),
        ("GET", "/model.json") => page(200, json, &ctx.model),
        ("GET", "/state.json") => {
            let (_, v) = ctx.shared.read(|l| view::state(&ctx.c, &ctx.machine, l));
            Answer::Page(200, json, v.to_string())
        }
        ("GET", "/events") => Answer::Events,
        ("POST", p) if p.starts_with("/command/") => {
            if rq.header("x-panel") != Some("button") {
                return page(
                    403,
                    plain,
                    "a button is pressed from the panel's own page (X-Panel: button)\n",
                );
            }
            let name = p.trim_start_matches("/command/");
            let (code, body) = command(ctx, name);
            Answer::Page(code, "text/plain; charset=utf-8", body)
        }
        _ => page(404, plain, "not found\n"),
    }
}

/// A button pressed: refused (409, why) unless the machine allows it now; else carried
/// out by the radio thread, and how it ended.
fn command(ctx: &Ctx, name: &str) -> (u16, String) {
    let Some(b) = Button::parse(name) else {
        return (404, format!("no button {name}"));
    };
    let (_, allowed) = ctx.shared.read(|l| buttons::check(b, &ctx.c, l));
    if let Err(why) = allowed {
        return (409, format!("refused: {why}"));
    }
    let (reply, outcome) = mpsc::channel();
    let claim = Claim::default();
    let order = Order {
        button: b,
        reply,
        claim: claim.clone(),
    };
    let sent = match ctx.orders.lock() {
        Ok(o) => o.try_send(order),
        Err(_) => return (503, "the panel's radio stopped".into()),
    };
    match sent {
        Ok(()) => outcome_of(name, &claim, &outcome, ORDER_WITHIN, ORDER_WITHIN),
        Err(TrySendError::Full(_)) => (
            503,
            format!("the panel is busy: {MAX_ORDERS} orders wait already; {name} was not sent"),
        ),
        Err(TrySendError::Disconnected(_)) => (503, "the panel's radio stopped".into()),
    }
}

/// How order `name` ended: its outcome, once the radio thread carried it out. An order
/// without an outcome `within` is given up on if the radio thread has not taken it (504,
/// and it is never carried out); one it took is waited for `then` more, its outcome then
/// unknown (504).
fn outcome_of(
    name: &str,
    claim: &Claim,
    outcome: &Receiver<Result<String, String>>,
    within: Duration,
    then: Duration,
) -> (u16, String) {
    let answer = |said: Result<String, String>| match said {
        Ok(said) => (200, said),
        Err(said) => (409, said),
    };
    if let Ok(said) = outcome.recv_timeout(within) {
        return answer(said);
    }
    if claim.give_up() {
        return (
            504,
            format!(
                "{name}: not carried out (the panel's radio did not take it within {} s)",
                within.as_secs()
            ),
        );
    }
    match outcome.recv_timeout(then) {
        Ok(said) => answer(said),
        Err(_) => (
            504,
            format!(
                "{name}: under way for {} s, its outcome unknown (see the machine's state)",
                (within + then).as_secs()
            ),
        ),
    }
}

/// Server-sent events: the state at once, then at every change (a comment now and then
/// without one), until the page goes away (or takes no write for
/// [`http::WRITE_WITHIN`]), a newcomer past [`MAX_STREAMS`] closes it (the oldest:
/// [`Streams`]) or the panel stops.
fn stream_events(ctx: &Ctx, mut out: TcpStream) {
    let Ok(_slot) = ctx.streams.open(&out) else {
        let _ = http::respond(&mut out, 503, "text/plain", "the panel is busy\n");
        return;
    };
    let _ = send_events(ctx, &mut out);
}

fn send_events(ctx: &Ctx, out: &mut dyn Write) -> io::Result<()> {
    out.write_all(
        format!(
            "HTTP/1.1 200 OK\r\nContent-Type: text/event-stream\r\n{}Connection: close\r\n\r\n",
            http::COMMON
        )
        .as_bytes(),
    )?;
    let mut seen = None;
    while !ctx.stop.load(Ordering::Relaxed) {
        let (version, v) = ctx.shared.read(|l| view::state(&ctx.c, &ctx.machine, l));
        if seen != Some(version) {
            out.write_all(format!("data: {v}\n\n").as_bytes())?;
            seen = Some(version);
        } else {
            out.write_all(b": still here\n\n")?;
        }
        out.flush()?;
        ctx.shared.wait_change(version, KEEPALIVE);
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_host_names_the_panel_by_its_address_or_a_loopback_name() {
        let at: SocketAddr = "127.0.0.1:15480".parse().expect("addr");
        for host in ["127.0.0.1:15480", "localhost:15480", "[::1]:15480"] {
            assert!(names_panel(Some(host), at), "{host}");
        }
        for host in [
            "evil.example:15480",
            "127.0.0.1:15481",
            "127.0.0.1",
            "localhost.:15480",
            "",
        ] {
            assert!(!names_panel(Some(host), at), "{host}");
        }
        assert!(!names_panel(None, at));
        let http: SocketAddr = "127.0.0.1:80".parse().expect("addr");
        assert!(names_panel(Some("localhost"), http));
        assert!(names_panel(Some("127.0.0.1:80"), http));
        let v6: SocketAddr = "[::1]:8080".parse().expect("addr");
        assert!(names_panel(Some("[::1]:8080"), v6));
        assert!(!names_panel(Some("[::2]:8080"), v6));
    }

    use std::io::Read;
    use std::time::Instant;

    /// A medium and a panel of the paint robot listening on `listen` (no radio: no button
    /// is carried out, which these tests do not need).
    fn panel_on(listen: &str) -> (medium::Medium, Panel) {
        let medium = medium::Medium::start(medium::Config::default()).expect("medium");
        let listener = Listener::bind(listen.parse().expect("addr")).expect("binds");
        let c = crate::model::tests::paint();
        let panel = Panel::start(listener, c, medium.addr(), None).expect("starts");
        (medium, panel)
    }

    /// Sends `bytes` to `at`; the answer, read to its end (within 5 s).
    fn exchange(at: SocketAddr, bytes: &[u8]) -> String {
        let mut s = TcpStream::connect(at).expect("connects");
        s.set_read_timeout(Some(Duration::from_secs(5)))
            .expect("timeout");
        s.write_all(bytes).expect("sends");
        let mut out = Vec::new();
        let _ = s.read_to_end(&mut out);
        String::from_utf8_lossy(&out).into_owned()
    }

    /// Another site's page may not frame the panel's (a frame under a decoy button would
    /// have the operator press START through it: on loopback the page needs no token).
    #[test]
    fn no_other_site_may_frame_the_page() {
        let (_medium, panel) = panel_on("127.0.0.1:0");
        let at = panel.addr();
        let answer = exchange(
            at,
            format!("GET / HTTP/1.1\r\nHost: {at}\r\n\r\n").as_bytes(),
        );
        let (head, _) = answer.split_once("\r\n\r\n").expect("a head");
        assert!(head.starts_with("HTTP/1.1 200 OK"), "{head}");
        assert!(head.contains("\r\nX-Frame-Options: DENY\r\n"), "{head}");
        assert!(
            head.contains("\r\nContent-Security-Policy: frame-ancestors 'none'\r\n"),
            "{head}"
        );
    }

    /// An `<img>` of another site's page asks for the event stream without an `Origin`;
    /// its browser says it is another site's: refused (it held a stream's slot).
    #[test]
    fn another_sites_image_opens_no_event_stream() {
        let (_medium, panel) = panel_on("127.0.0.1:0");
        let at = panel.addr();
        let rq = format!(
            "GET /events HTTP/1.1\r\nHost: {at}\r\nSec-Fetch-Site: cross-site\r\n\
             Sec-Fetch-Mode: no-cors\r\nSec-Fetch-Dest: image\r\n\r\n"
        );
        let answer = exchange(at, rq.as_bytes());
        assert!(answer.starts_with("HTTP/1.1 403 Forbidden\r\n"), "{answer}");
    }

    /// One client holding every connection with heads it never finishes: the oldest are
    /// closed as newer ones come (past MAX_HEADS), so the operator's page is still served
    /// (it got 503 until the heads' 5 s deadline, and the client opened more).
    #[test]
    fn heads_never_finished_keep_no_page_out() {
        let (_medium, panel) = panel_on("127.0.0.1:0");
        let at = panel.addr();
        let slow: Vec<TcpStream> = (0..MAX_CONNECTIONS)
            .map(|_| {
                let mut s = TcpStream::connect(at).expect("connects");
                s.write_all(b"GET / HTTP/1.1\r\nX: ").expect("sends");
                s.set_nonblocking(true).expect("nonblocking");
                s
            })
            .collect();
        // The panel closes the oldest heads, answering nothing (before the 5 s deadline,
        // which answers 408): wait for those closes.
        let want = MAX_CONNECTIONS - MAX_HEADS;
        let mut closed = vec![false; slow.len()];
        let until = Instant::now() + Duration::from_millis(4_500);
        while closed.iter().filter(|c| **c).count() < want && Instant::now() < until {
            for (s, c) in slow.iter().zip(closed.iter_mut()).filter(|(_, c)| !**c) {
                match (&*s).read(&mut [0u8; 64]) {
                    Ok(0) => *c = true,
                    Ok(n) => panic!("answered {n} bytes"),
                    Err(_) => {}
                }
            }
            std::thread::yield_now();
        }
        assert_eq!(
            closed.iter().filter(|c| **c).count(),
            want,
            "closed by the panel"
        );
        // The operator's page: served (once the closed heads' threads are gone).
        let get = format!("GET /state.json HTTP/1.1\r\nHost: {at}\r\n\r\n");
        let served = (0..100).any(|_| exchange(at, get.as_bytes()).starts_with("HTTP/1.1 200 OK"));
        assert!(served, "the operator's page was refused");
    }

    #[test]
    fn an_order_the_page_gave_up_on_is_never_carried_out() {
        let (_reply, outcome) = mpsc::channel();
        let claim = Claim::default();
        let (code, said) = outcome_of("START", &claim, &outcome, Duration::ZERO, Duration::ZERO);
        assert_eq!(
            (code, said.as_str()),
            (
                504,
                "START: not carried out (the panel's radio did not take it within 0 s)"
            )
        );
        // The radio thread comes to it later: it does not take it.
        assert!(!claim.take());
    }

    #[test]
    fn an_order_under_way_is_waited_for_past_the_first_wait() {
        let (reply, outcome) = mpsc::channel();
        let claim = Claim::default();
        assert!(claim.take());
        let radio = std::thread::spawn(move || {
            reply.send(Ok("HOME: homed".to_string())).unwrap();
        });
        // The first wait ends before the outcome (or not): taken, it is waited for again.
        let long = Duration::from_secs(600);
        let (code, said) = outcome_of("HOME", &claim, &outcome, Duration::ZERO, long);
        radio.join().unwrap();
        assert_eq!((code, said.as_str()), (200, "HOME: homed"));
        assert!(!claim.give_up());
    }

    #[test]
    fn tokens_compare_by_value() {
        assert!(same("0a1b", "0a1b"));
        assert!(!same("0a1b", "0a1c"));
        assert!(!same("0a1b", "0a1"));
    }
}
