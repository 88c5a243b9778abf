//! The panel's HTTP server (tiny_http, a thread per request): the page and its two
//! scripts' worth of files (embedded, nothing fetched from elsewhere), `model.json`,
//! `state.json`, `events` (server-sent events: the state again at every change) and
//! `POST command/NAME`. Off loopback every request must carry the token printed at
//! start-up (`?token=`).

use std::io::{self, Write};
use std::net::{SocketAddr, TcpListener};
use std::sync::atomic::{AtomicBool, AtomicUsize, Ordering};
use std::sync::mpsc::{self, Sender};
use std::sync::{Arc, Mutex};
use std::thread::JoinHandle;
use std::time::Duration;

use robot_compiler::compile::Compiled;
use robot_keys::MachineSecret;
use robot_net::radio::ToolRadio;
use tiny_http::{Header, Method, Request, Response, Server};

use crate::buttons::{self, Button};
use crate::error::PanelError;
use crate::live::Live;
use crate::model::Machine;
use crate::poll::{self, Order};
use crate::shared::Shared;
use crate::{feed, view};

const INDEX: &str = include_str!("page/index.html");
const SCRIPT: &str = include_str!("page/panel.js");
const STYLE: &str = include_str!("page/panel.css");

/// At most this many pages stream at once (each holds a thread).
const MAX_STREAMS: usize = 32;
/// At most this many other requests are served at once (each holds a thread).
const MAX_REQUESTS: usize = 64;
/// A stream with no change says something this often (a page that went away is found).
const KEEPALIVE: Duration = Duration::from_secs(5);
/// The longest an order may take (homing waits for the machine).
const ORDER_WITHIN: Duration = Duration::from_secs(120);

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
    server: Arc<Server>,
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
    orders: Mutex<Sender<Order>>,
    token: Option<String>,
    streams: AtomicUsize,
    requests: AtomicUsize,
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
        let (orders, inbox) = mpsc::channel();
        let run = Run {
            c: c.clone(),
            machine: machine.clone(),
            shared: shared.clone(),
            inbox,
        };
        let addr = listener.addr;
        let server = Arc::new(Server::from_listener(listener.listener, None).map_err(|e| {
            PanelError::Listen {
                addr,
                source: io::Error::other(e.to_string()),
            }
        })?);
        let ctx = Arc::new(Ctx {
            c,
            machine,
            model,
            shared,
            orders: Mutex::new(orders),
            token: token.clone(),
            streams: AtomicUsize::new(0),
            requests: AtomicUsize::new(0),
            stop: stop.clone(),
        });
        let (srv, flag) = (server.clone(), stop.clone());
        let accept = std::thread::Builder::new()
            .name("panel-http".into())
            .spawn(move || {
                while !flag.load(Ordering::Relaxed) {
                    let Ok(Some(rq)) = srv.recv_timeout(Duration::from_millis(200)) else {
                        continue;
                    };
                    if ctx.requests.fetch_add(1, Ordering::SeqCst) >= MAX_REQUESTS {
                        ctx.requests.fetch_sub(1, Ordering::SeqCst);
                        let _ = rq.respond(text(503, "text/plain", "the panel is busy\n"));
                        continue;
                    }
                    let ctx = ctx.clone();
                    let spawned = std::thread::Builder::new()
                        .name("panel-request".into())
                        .spawn({
                            let ctx = ctx.clone();
                            move || {
                                handle(&ctx, rq);
                                ctx.requests.fetch_sub(1, Ordering::SeqCst);
                            }
                        });
                    if spawned.is_err() {
                        ctx.requests.fetch_sub(1, Ordering::SeqCst);
                    }
                }
            })
            .map_err(PanelError::Thread)?;
        Ok(Panel {
            addr,
            run: Some(run),
            token,
            server,
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
        self.server.unblock();
    }
}

/// The path and the query's token.
fn split(url: &str) -> (&str, Option<&str>) {
    let (path, query) = url.split_once('?').unwrap_or((url, ""));
    let token = query.split('&').find_map(|kv| kv.strip_prefix("token="));
    (path, token)
}

fn text(code: u16, kind: &str, body: impl Into<String>) -> Response<io::Cursor<Vec<u8>>> {
    let mut r = Response::from_string(body.into()).with_status_code(code);
    // Both headers are ASCII constants of this file.
    for (name, value) in [("Content-Type", kind), ("Cache-Control", "no-store")] {
        if let Ok(h) = Header::from_bytes(name.as_bytes(), value.as_bytes()) {
            r.add_header(h);
        }
    }
    r
}

fn handle(ctx: &Ctx, rq: Request) {
    let (path, token) = split(rq.url());
    let path = path.to_string();
    // The script and the style say nothing of the machine: fetched without the token.
    let open = matches!(path.as_str(), "/panel.js" | "/panel.css");
    if !open && ctx.token.is_some() && token != ctx.token.as_deref() {
        let _ = rq.respond(text(
            403,
            "text/plain",
            "this panel listens off loopback: open the address it printed at start-up, \
             with its token\n",
        ));
        return;
    }
    let json = "application/json";
    let response = match (rq.method(), path.as_str()) {
        (Method::Get, "/") => text(200, "text/html; charset=utf-8", INDEX),
        (Method::Get, "/panel.js") => text(200, "text/javascript", SCRIPT),
        (Method::Get, "/panel.css") => text(200, "text/css", STYLE),
        (Method::Get, "/model.json") => text(200, json, ctx.model.clone()),
        (Method::Get, "/state.json") => {
            let (_, v) = ctx.shared.read(|l| view::state(&ctx.c, &ctx.machine, l));
            text(200, json, v.to_string())
        }
        (Method::Get, "/events") => return stream(ctx, rq),
        (Method::Post, p) if p.starts_with("/command/") => {
            let name = p.trim_start_matches("/command/");
            let (code, body) = command(ctx, name);
            text(code, "text/plain; charset=utf-8", body)
        }
        _ => text(404, "text/plain", "not found\n"),
    };
    let _ = rq.respond(response);
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
    let sent = ctx
        .orders
        .lock()
        .map(|o| o.send(Order { button: b, reply }).is_ok())
        .unwrap_or(false);
    if !sent {
        return (503, "the panel's radio stopped".into());
    }
    match outcome.recv_timeout(ORDER_WITHIN) {
        Ok(Ok(said)) => (200, said),
        Ok(Err(said)) => (409, said),
        Err(_) => (
            504,
            format!("{name}: no outcome within {} s", ORDER_WITHIN.as_secs()),
        ),
    }
}

/// Server-sent events: the state at once, then at every change (a comment now and then
/// without one), until the page goes away or the panel stops.
fn stream(ctx: &Ctx, rq: Request) {
    if ctx.streams.fetch_add(1, Ordering::SeqCst) >= MAX_STREAMS {
        ctx.streams.fetch_sub(1, Ordering::SeqCst);
        let _ = rq.respond(text(503, "text/plain", "too many pages open\n"));
        return;
    }
    let mut out = rq.into_writer();
    let _ = send_events(ctx, &mut out);
    ctx.streams.fetch_sub(1, Ordering::SeqCst);
}

fn send_events(ctx: &Ctx, out: &mut dyn Write) -> io::Result<()> {
    out.write_all(
        b"HTTP/1.1 200 OK\r\nContent-Type: text/event-stream\r\nCache-Control: no-store\r\n\
          Connection: close\r\n\r\n",
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
