//! Shared by the panel's tests: a running demo machine (the bed's medium, node processes
//! and plant, pushed by `config-tool push` with the bed's key file), `config-tool panel`
//! on it, a small HTTP/1.1 client (for the panel and for WebDriver), the panel's
//! server-sent events read until a condition holds, and a WebDriver session of Debian's
//! headless chromium.
#![allow(dead_code)]

use std::io::{BufRead, BufReader, Read, Write};
use std::net::{SocketAddr, TcpListener, TcpStream};
use std::path::{Path, PathBuf};
use std::process::{Child, Command, Stdio};
use std::time::Instant;

use serde_json::{json, Value};

use crate::e2e_support::{self, TempDir, TIMEOUT};
use robot_net::demo::{self, Bed};
use robot_net::live_plant::{self, Injection};

pub const ROBOT: &str = "robot-configs/paint-robot.ron";

/// A process killed (and reaped) when dropped.
pub struct Killed(pub Child);

impl Drop for Killed {
    fn drop(&mut self) {
        let _ = self.0.kill();
        let _ = self.0.wait();
    }
}

/// The paint robot running on this host: the bed (medium, one node process per node,
/// the plant, with `injection`), its machine secret in a key file, every role pushed.
pub struct Machine {
    pub bed: Bed,
    pub dir: TempDir,
    pub key: PathBuf,
    /// The robot file, from the workspace root.
    pub robot: String,
}

impl Machine {
    /// The paint robot.
    pub fn up(tag: &str, injection: Option<Injection>) -> Machine {
        Machine::of("paint-robot.ron", tag, injection)
    }

    /// `robot-configs/NAME`.
    pub fn of(name: &str, tag: &str, injection: Option<Injection>) -> Machine {
        let c = e2e_support::robot(name, 1);
        let dir = TempDir::new(tag);
        let mut bed =
            Bed::start(e2e_support::options(medium::Config::default(), None)).expect("bed");
        let key = dir.0.join("machine.key");
        let secret = bed.secret().expect("a secured bed").clone();
        let text = robot_keys::file::machine_secret_text(&secret);
        robot_keys::write_secret_file(&key, text.as_bytes(), false).expect("key file");
        let addrs = demo::node_addrs(&c);
        for a in &addrs {
            bed.start_node(*a).expect("node process");
        }
        let actuators = live_plant::actuators(&c).expect("actuators");
        bed.set_plant_injected(actuators, injection).expect("plant");
        // Scans in clear: the tool's counter file is the only one to secure frames.
        bed.wait_for_nodes(&addrs)
            .expect("every node announces itself");
        let robot = format!("robot-configs/{name}");
        let m = Machine {
            bed,
            dir,
            key,
            robot,
        };
        let pushed = m.tool(&["push", &m.robot]);
        assert!(
            pushed.status.success(),
            "{}{}",
            text_of(&pushed.stdout),
            text_of(&pushed.stderr)
        );
        m
    }

    pub fn medium(&self) -> String {
        self.bed.medium().addr().to_string()
    }

    /// `config-tool ARGS --keys KEY --medium M`, from the workspace root.
    pub fn tool(&self, args: &[&str]) -> std::process::Output {
        Command::new(env!("CARGO_BIN_EXE_config-tool"))
            .current_dir(root())
            .args(args)
            .arg("--keys")
            .arg(&self.key)
            .args(["--medium", &self.medium()])
            .env_remove("CONFIG_TOOL_KEYS")
            .output()
            .expect("runs")
    }

    /// `config-tool panel ROBOT` on this machine, on a free loopback port.
    pub fn panel(&self) -> Panel {
        Panel::start(&[
            &self.robot,
            "--keys",
            self.key.to_str().expect("utf-8 path"),
            "--medium",
            &self.medium(),
            "--listen",
            "127.0.0.1:0",
        ])
        .expect("the panel starts")
    }
}

pub fn root() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("..")
}

pub fn text_of(b: &[u8]) -> String {
    String::from_utf8_lossy(b).into_owned()
}

/// A running `config-tool panel`: its address and page, from its first line.
pub struct Panel {
    pub process: Killed,
    pub addr: SocketAddr,
    pub url: String,
}

impl Panel {
    /// Starts `config-tool panel ARGS`; `Err` with its stderr if it ends before saying
    /// where it serves.
    pub fn start(args: &[&str]) -> Result<Panel, (Option<i32>, String)> {
        let mut child = Command::new(env!("CARGO_BIN_EXE_config-tool"))
            .current_dir(root())
            .arg("panel")
            .args(args)
            .env_remove("CONFIG_TOOL_KEYS")
            .stdin(Stdio::null())
            .stdout(Stdio::piped())
            .stderr(Stdio::piped())
            .spawn()
            .expect("runs");
        let out = child.stdout.take().expect("stdout");
        let mut first = String::new();
        let mut out = BufReader::new(out);
        let _ = out.read_line(&mut first);
        // The rest of what it prints (the token's line) read too: a pipe closed under it
        // would end the panel at its next line.
        std::thread::spawn(move || std::io::copy(&mut out, &mut std::io::sink()));
        let Some(url) = first.trim().split(" on ").nth(1).map(str::to_string) else {
            let mut err = String::new();
            if let Some(mut e) = child.stderr.take() {
                let _ = e.read_to_string(&mut err);
            }
            let status = child.wait().ok().and_then(|s| s.code());
            return Err((status, err));
        };
        let addr = url
            .trim_start_matches("http://")
            .split('/')
            .next()
            .and_then(|a| a.parse().ok())
            .unwrap_or_else(|| panic!("an address in {first:?}"));
        Ok(Panel {
            process: Killed(child),
            addr,
            url,
        })
    }

    pub fn get(&self, path: &str) -> (u16, String) {
        request(self.addr, "GET", path, None)
    }

    /// A button pressed as the panel's page presses it.
    pub fn press(&self, button: &str) -> (u16, String) {
        let path = format!("/command/{button}");
        request_with(self.addr, "POST", &path, Some(""), "X-Panel: button\r\n")
    }

    /// The panel's server-sent events.
    pub fn events(&self) -> Events {
        Events::open(self.addr)
    }
}

/// One HTTP/1.1 request (`Connection: close`): the status and the body.
pub fn request(addr: SocketAddr, method: &str, path: &str, body: Option<&str>) -> (u16, String) {
    request_with(addr, method, path, body, "")
}

/// [`request`] with more header lines (each ending in CRLF).
pub fn request_with(
    addr: SocketAddr,
    method: &str,
    path: &str,
    body: Option<&str>,
    headers: &str,
) -> (u16, String) {
    let mut s = TcpStream::connect_timeout(&addr, TIMEOUT).expect("connects");
    s.set_read_timeout(Some(TIMEOUT)).expect("timeout");
    let body = body.unwrap_or("");
    let head = format!(
        "{method} {path} HTTP/1.1\r\nHost: {addr}\r\nConnection: close\r\nContent-Type: \
         application/json\r\n{headers}Content-Length: {}\r\n\r\n",
        body.len()
    );
    s.write_all(head.as_bytes()).expect("sends");
    s.write_all(body.as_bytes()).expect("sends");
    // Read by its length (chromedriver keeps the connection open whatever it is asked).
    let mut r = BufReader::new(s);
    let mut head = String::new();
    loop {
        let mut line = String::new();
        let n = r.read_line(&mut line).expect("an answer");
        if n == 0 || line == "\r\n" {
            break;
        }
        head.push_str(&line);
    }
    let status = head
        .split(' ')
        .nth(1)
        .and_then(|c| c.parse().ok())
        .unwrap_or_else(|| panic!("a status in {head:?}"));
    let lower = head.to_ascii_lowercase();
    let length = lower
        .lines()
        .find_map(|l| l.strip_prefix("content-length:"))
        .and_then(|n| n.trim().parse::<usize>().ok());
    let mut body = Vec::new();
    match length {
        Some(n) => {
            body.resize(n, 0);
            r.read_exact(&mut body).expect("the whole body");
        }
        None if lower.contains("transfer-encoding: chunked") => loop {
            let mut size = String::new();
            r.read_line(&mut size).expect("a chunk");
            let n = usize::from_str_radix(size.trim(), 16).unwrap_or(0);
            if n == 0 {
                break;
            }
            let mut chunk = vec![0; n + 2];
            r.read_exact(&mut chunk).expect("the chunk");
            body.extend_from_slice(&chunk[..n]);
        },
        None => {
            r.read_to_end(&mut body).expect("the body");
        }
    }
    (status, text_of(&body))
}

/// The panel's `events` stream, read event by event.
pub struct Events {
    reader: BufReader<TcpStream>,
}

impl Events {
    fn open(addr: SocketAddr) -> Events {
        let mut s = TcpStream::connect_timeout(&addr, TIMEOUT).expect("connects");
        s.set_read_timeout(Some(TIMEOUT)).expect("timeout");
        write!(s, "GET /events HTTP/1.1\r\nHost: {addr}\r\n\r\n").expect("sends");
        Events {
            reader: BufReader::new(s),
        }
    }

    /// Reads states until `ok` takes one (bounded by [`TIMEOUT`]); the last state seen
    /// is in the panic message.
    pub fn until(&mut self, what: &str, ok: impl Fn(&Value) -> bool) -> Value {
        let end = Instant::now() + TIMEOUT;
        let mut last = Value::Null;
        while Instant::now() < end {
            let mut line = String::new();
            match self.reader.read_line(&mut line) {
                Ok(0) | Err(_) => break,
                Ok(_) => {}
            }
            if let Some(data) = line.strip_prefix("data: ") {
                last = serde_json::from_str(data).expect("a state");
                if ok(&last) {
                    return last;
                }
            }
        }
        panic!("the panel never showed {what}; last state: {last:#}");
    }
}

/// What the browser test needs installed, said when it is missing.
pub const INSTALL: &str = "the panel's browser test needs Debian's headless chromium and \
                           its WebDriver: apt-get install -y chromium chromium-driver";

/// A WebDriver session of headless chromium (`chromedriver`, the W3C protocol spoken
/// directly: a handful of JSON requests).
pub struct Browser {
    _driver: Driver,
    addr: SocketAddr,
    session: String,
}

/// The chromedriver process: asked to shut down (it closes the browsers it started)
/// before it is killed, so no browser outlives the test, even one that failed.
struct Driver {
    process: Killed,
    addr: SocketAddr,
}

impl Drop for Driver {
    fn drop(&mut self) {
        let _ = TcpStream::connect_timeout(&self.addr, TIMEOUT).and_then(|mut s| {
            s.set_read_timeout(Some(TIMEOUT))?;
            write!(s, "GET /shutdown HTTP/1.1\r\nHost: {}\r\n\r\n", self.addr)?;
            // Its answer, or the connection closing as it exits.
            let _ = s.read(&mut [0u8; 256]);
            Ok(())
        });
        // Then killed and reaped (`Killed`).
    }
}

impl Browser {
    pub fn start() -> Browser {
        let port = TcpListener::bind("127.0.0.1:0")
            .and_then(|l| l.local_addr())
            .expect("a free port")
            .port();
        let mut driver = match Command::new("chromedriver")
            .arg(format!("--port={port}"))
            .stdin(Stdio::null())
            .stdout(Stdio::piped())
            .stderr(Stdio::null())
            .spawn()
        {
            Ok(d) => d,
            Err(e) => panic!("cannot run chromedriver ({e}): {INSTALL}"),
        };
        // Ready once it says so (its first lines), not after a time.
        let out = driver.stdout.take().expect("stdout");
        let mut lines = BufReader::new(out).lines();
        let ready = lines
            .by_ref()
            .map_while(Result::ok)
            .any(|l| l.contains("started successfully"));
        assert!(ready, "chromedriver did not start: {INSTALL}");
        std::thread::spawn(move || for _ in lines {});
        let addr: SocketAddr = ([127, 0, 0, 1], port).into();
        let driver = Driver {
            process: Killed(driver),
            addr,
        };
        let binary = ["/usr/bin/chromium", "/usr/bin/chromium-browser"]
            .into_iter()
            .find(|p| Path::new(p).exists())
            .unwrap_or_else(|| panic!("no chromium binary: {INSTALL}"));
        let caps = json!({"capabilities": {"alwaysMatch": {
            "browserName": "chrome",
            "goog:chromeOptions": {
                "binary": binary,
                "args": ["--headless=new", "--no-sandbox", "--disable-gpu",
                         "--disable-dev-shm-usage", "--window-size=1280,1700"]
            }
        }}});
        let (_, v) = wd(addr, "POST", "/session", Some(&caps));
        let session = v["value"]["sessionId"]
            .as_str()
            .unwrap_or_else(|| panic!("no session: {v:#} ({INSTALL})"))
            .to_string();
        let b = Browser {
            _driver: driver,
            addr,
            session,
        };
        b.call(
            "POST",
            "timeouts",
            json!({"script": TIMEOUT.as_millis() as u64}),
        );
        b
    }

    fn call(&self, method: &str, path: &str, body: Value) -> Value {
        let path = format!("/session/{}/{path}", self.session);
        let body = (method == "POST").then_some(&body);
        let (status, v) = wd(self.addr, method, &path, body);
        assert_eq!(status, 200, "WebDriver {method} {path}: {v:#}");
        v["value"].clone()
    }

    pub fn goto(&self, url: &str) {
        self.call("POST", "url", json!({ "url": url }));
    }

    /// `script`'s value in the page.
    pub fn eval(&self, script: &str) -> Value {
        self.call(
            "POST",
            "execute/sync",
            json!({"script": script, "args": []}),
        )
    }

    /// Waits, in the page, until the JavaScript expression `cond` is truthy: checked now and
    /// at every change of the page (a MutationObserver), bounded by the script timeout.
    /// Its value.
    pub fn wait_for(&self, cond: &str) -> Value {
        let script = r#"
            const cond = new Function("return (" + arguments[0] + ");");
            const done = arguments[arguments.length - 1];
            let obs = null;
            const check = () => {
                let v = null;
                try { v = cond(); } catch (e) { v = null; }
                if (v) { if (obs) obs.disconnect(); done(v); return true; }
                return false;
            };
            if (!check()) {
                obs = new MutationObserver(check);
                obs.observe(document.documentElement,
                    { subtree: true, childList: true, attributes: true, characterData: true });
            }
        "#;
        let path = format!("/session/{}/execute/async", self.session);
        let body = json!({"script": script, "args": [cond]});
        let (status, v) = wd(self.addr, "POST", &path, Some(&body));
        if status != 200 {
            let page = self.eval("return document.body.innerText;");
            panic!(
                "the page never showed `{cond}`: {}\npage:\n{}",
                v["value"]["message"],
                page.as_str().unwrap_or("")
            );
        }
        v["value"].clone()
    }

    /// Clicks the element `css` selects (as a person would: WebDriver's element click).
    pub fn click(&self, css: &str) {
        let e = self.call(
            "POST",
            "element",
            json!({"using": "css selector", "value": css}),
        );
        let id = e["element-6066-11e4-a52e-4f735466cecf"]
            .as_str()
            .unwrap_or_else(|| panic!("no element {css}: {e:#}"))
            .to_string();
        self.call("POST", &format!("element/{id}/click"), json!({}));
    }

    /// A PNG of the window, written to `path`.
    pub fn screenshot(&self, path: &Path) {
        let v = self.call("GET", "screenshot", json!({}));
        let png = base64(v.as_str().expect("base64"));
        assert_eq!(&png[..8], b"\x89PNG\r\n\x1a\n", "a PNG");
        std::fs::write(path, png).expect("writes the screenshot");
    }
}

impl Drop for Browser {
    fn drop(&mut self) {
        let path = format!("/session/{}", self.session);
        let _ = wd(self.addr, "DELETE", &path, None);
    }
}

fn wd(addr: SocketAddr, method: &str, path: &str, body: Option<&Value>) -> (u16, Value) {
    let body = body.map(Value::to_string);
    let (status, text) = request(addr, method, path, body.as_deref());
    let v = serde_json::from_str(&text).unwrap_or(Value::String(text));
    (status, v)
}

/// Standard base64 (what WebDriver sends a screenshot in), decoded.
fn base64(text: &str) -> Vec<u8> {
    let value = |c: u8| match c {
        b'A'..=b'Z' => Some(c - b'A'),
        b'a'..=b'z' => Some(c - b'a' + 26),
        b'0'..=b'9' => Some(c - b'0' + 52),
        b'+' => Some(62),
        b'/' => Some(63),
        _ => None,
    };
    let mut out = Vec::with_capacity(text.len() * 3 / 4);
    let (mut acc, mut bits) = (0u32, 0);
    for v in text.bytes().filter_map(value) {
        acc = (acc << 6) | u32::from(v);
        bits += 6;
        if bits >= 8 {
            bits -= 8;
            out.push((acc >> bits) as u8);
        }
    }
    out
}

#[test]
fn base64_decodes_what_webdriver_sends() {
    assert_eq!(base64("iVBORw0KGgo="), b"\x89PNG\r\n\x1a\n");
    assert_eq!(base64("TWFu"), b"Man");
}

/// A directory with a new `machine.key` (made by `config-tool keys new`) and a medium with
/// no node on it: what a panel needs that is not a machine.
pub fn keyed_medium(tag: &str) -> (TempDir, medium::Medium) {
    let dir = TempDir::new(tag);
    let key = dir.0.join("machine.key");
    let made = std::process::Command::new(env!("CARGO_BIN_EXE_config-tool"))
        .args(["keys", "new", "--out", key.to_str().unwrap()])
        .output()
        .unwrap();
    assert!(made.status.success());
    let medium = medium::Medium::start(medium::Config::default()).unwrap();
    (dir, medium)
}

/// A panel of the paint robot listening on `listen`, on a medium with no node (with what
/// it needs: its directory and key, the medium).
pub fn panel_on(tag: &str, listen: &str) -> (TempDir, medium::Medium, Panel) {
    let (dir, medium) = keyed_medium(tag);
    let (k, m) = (dir.0.join("machine.key"), medium.addr().to_string());
    let k = k.to_str().unwrap();
    let panel =
        Panel::start(&[ROBOT, "--keys", k, "--medium", &m, "--listen", listen]).expect("the panel");
    (dir, medium, panel)
}
