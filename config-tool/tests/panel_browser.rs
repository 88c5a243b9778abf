//! `config-tool panel` in a real browser: Debian's headless chromium driven over WebDriver
//! against the paint robot running on this host (node processes, plant, medium). The page
//! shows four actuator lanes and the steps in sequence order; HOME, then START runs
//! cycles (the cycle advances, cycles are counted); a jammed cylinder (injected by the
//! plant in the second cycle) shows as a latched fault alarm that ACK cannot clear until
//! RESET; then it clears. A node that stops answering and the medium going away are said
//! on the page. Screenshots of three points are saved under the target directory.
//! Without chromium and chromedriver the test fails, saying what to install.

mod e2e_support;
mod panel_support;

use std::path::PathBuf;

use e2e_support::SEQUENCE_1;
use panel_support::{Browser, Machine};
use robot_net::live_plant::{Injection, Jam};

fn shots() -> PathBuf {
    let dir = PathBuf::from(env!("CARGO_TARGET_TMPDIR")).join("panel");
    std::fs::create_dir_all(&dir).expect("screenshot directory");
    dir
}

fn enabled(name: &str) -> String {
    format!("!document.getElementById('{name}').disabled")
}

#[test]
fn the_panel_shows_the_running_paint_robot_and_its_buttons_work_in_a_real_browser() {
    // HC is jammed from its first stroke of the second cycle on (step 4 of cycle 2).
    let jam = Injection {
        after: 12 + 3,
        actuator: 2,
        kind: Jam::Stuck,
    };
    let mut m = Machine::up("panel-browser", Some(jam));
    let panel = m.panel();
    let browser = Browser::start();
    let dir = shots();
    browser.goto(&panel.url);

    assert_eq!(
        browser.wait_for("document.querySelectorAll('.lane.actuator').length === 4 && 4"),
        4
    );
    let lanes = browser.eval(
        "return Array.from(document.querySelectorAll('.lane.actuator')).map(l => l.dataset.name);",
    );
    assert_eq!(lanes, serde_json::json!(["VC", "GR", "HC", "RC"]));
    let steps = browser
        .eval("return Array.from(document.querySelectorAll('#steps li')).map(l => l.textContent).join(' ');");
    assert_eq!(steps, SEQUENCE_1);
    // Pushed, not homed: HOME is offered, START is not (and says why).
    browser.wait_for(&enabled("HOME"));
    assert_eq!(
        browser.eval("return document.getElementById('START').title;"),
        "not homed: HOME first"
    );
    browser.click("#HOME");
    browser.wait_for(&enabled("START"));
    assert_eq!(
        browser.eval("return document.getElementById('said').textContent.split(' in ')[0];"),
        "homed: every chart idle"
    );
    browser.screenshot(&dir.join("1-homed.png"));

    browser.click("#START");
    // The cycle advances: the third step lit, then the first cycle counted while the
    // second runs.
    browser.wait_for("document.querySelector('#steps li.current[data-index=\"2\"]')");
    browser.wait_for(
        "Number(document.getElementById('cycles').textContent) >= 1 && \
         document.querySelector('#steps li.current[data-index=\"1\"]')",
    );
    let times = browser.eval("return document.getElementById('cycle-ms').textContent;");
    assert!(
        times.as_str().is_some_and(|t| t.ends_with(" ms")),
        "{times}"
    );
    browser.screenshot(&dir.join("2-running.png"));

    // HC jammed: its watchdog faults it, a latched fault alarm; ACK refused while the
    // node is faulted, RESET offered.
    let alarm = browser.wait_for(
        "Array.from(document.querySelectorAll(\
         'tr.alarm[data-level=\"fault\"][data-latched=\"true\"]'))\
         .map(r => Array.from(r.cells).map(c => c.textContent).join(' | '))\
         .find(t => t.includes('0x0013 HC'))",
    );
    let alarm = alarm.as_str().unwrap_or_default().to_string();
    let cells: Vec<&str> = alarm.split(" | ").collect();
    assert_eq!(cells.len(), 5, "{alarm}");
    assert_eq!((cells[0], cells[2]), ("fault", "0x0013 HC"), "{alarm}");
    assert!(cells[1].ends_with(" UTC"), "{alarm}");
    assert!(cells[3].contains("watchdog"), "{alarm}");
    assert_eq!(cells[4], "latched, cause persists", "{alarm}");
    browser.wait_for(&enabled("RESET"));
    assert_eq!(
        browser.eval("return [document.getElementById('ACK').disabled, document.getElementById('START').disabled];"),
        serde_json::json!([true, true])
    );
    browser.screenshot(&dir.join("3-fault.png"));
    browser.click("#RESET");
    browser.wait_for(&enabled("ACK"));
    browser.click("#ACK");
    browser.wait_for(
        "document.querySelectorAll('tr.alarm').length > 0 && \
         document.querySelectorAll('tr.alarm[data-latched=\"true\"]').length === 0",
    );
    // Not homed after the reset: HOME is offered again.
    browser.wait_for(&enabled("HOME"));

    // A node that stops answering, then the medium going away: the page says so.
    m.bed.kill_node(0x0014);
    let banner = browser.wait_for(
        "(t => t.startsWith('Not answering') && t)(document.getElementById('banner').textContent)",
    );
    assert_eq!(banner, "Not answering: RC (0x0014)");
    browser.wait_for("document.getElementById('HOME').disabled");
    m.bed.medium().stop();
    let banner = browser.wait_for(
        "(t => t.startsWith('The medium is gone') && t)(document.getElementById('banner').textContent)",
    );
    assert_eq!(
        banner,
        "The medium is gone: the medium closed. Nothing can be commanded."
    );
}

/// Off loopback, the address the panel prints (with its token) opens the page in a real
/// browser, which then runs on a cookie: the token is gone from the address bar (and so
/// from the history and any `Referer`), no script of the page can read it, and the page
/// still loads its model and opens its event stream.
#[test]
fn off_loopback_the_token_leaves_the_address_for_a_cookie_and_the_page_runs() {
    let (_dir, _medium, panel) = panel_support::panel_on("panel-browser-token", "0.0.0.0:0");
    let (_, token) = panel.url.split_once("?token=").expect("a token");
    let browser = Browser::start();
    browser.goto(&format!(
        "http://127.0.0.1:{}/?token={token}",
        panel.addr.port()
    ));
    assert_eq!(
        browser.wait_for("document.querySelectorAll('.lane.actuator').length === 4 && 4"),
        4
    );
    browser.wait_for("document.getElementById('link').textContent === 'live'");
    assert_eq!(
        browser.eval("return [location.pathname, location.search, document.cookie];"),
        serde_json::json!(["/", "", ""])
    );
}
