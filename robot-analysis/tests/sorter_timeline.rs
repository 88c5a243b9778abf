//! `sim --timeline` of the ball-sorting station (`robot-configs/ball-sorter.ron`): the
//! SVG's lanes (pusher, gates, sensors, one per ball, then the charts and the radio), in
//! order, with their intervals and marks at their exact times.

use robot_analysis::sorter;
use robot_analysis::timeline::station;

mod common;
use common::{build, load};

const SORTER: &str = "../robot-configs/ball-sorter.ron";

fn svg_of(c: &robot_compiler::Compiled, balls: &str) -> String {
    let s = c.robot.sorting.as_ref().expect("a station");
    let feed = sorter::parse_feed(s, balls).expect("a feed");
    let run = sorter::simulate(c, Some(&feed)).expect("runs");
    station::svg(c, &run).expect("draws")
}

fn lanes(doc: &roxmltree::Document, kind: &str) -> Vec<String> {
    let class = format!("lane {kind}");
    doc.descendants()
        .filter(|n| n.attribute("class") == Some(class.as_str()))
        .map(|n| n.attribute("data-name").unwrap_or("").to_string())
        .collect()
}

fn lane<'a>(doc: &'a roxmltree::Document, kind: &str, name: &str) -> roxmltree::Node<'a, 'a> {
    let class = format!("lane {kind}");
    doc.descendants()
        .find(|n| {
            n.attribute("class") == Some(class.as_str()) && n.attribute("data-name") == Some(name)
        })
        .unwrap_or_else(|| panic!("no {kind} lane {name}"))
}

fn ms(n: roxmltree::Node, attr: &str) -> u64 {
    n.attribute(attr)
        .and_then(|v| v.parse().ok())
        .unwrap_or_else(|| panic!("{attr} of {n:?}"))
}

/// (state, from, to) of a lane's `state` rects.
fn states(n: roxmltree::Node) -> Vec<(String, u64, u64)> {
    n.children()
        .filter(|c| c.attribute("class") == Some("state"))
        .map(|c| {
            let s = c.attribute("data-state").unwrap_or("").to_string();
            (s, ms(c, "data-from"), ms(c, "data-to"))
        })
        .collect()
}

/// (from, to) of a lane's rects of class `class`.
fn spans(n: roxmltree::Node, class: &str) -> Vec<(u64, u64)> {
    n.children()
        .filter(|c| c.attribute("class") == Some(class))
        .map(|c| (ms(c, "data-from"), ms(c, "data-to")))
        .collect()
}

/// (class, automaton, t) of a ball lane's selection marks, in document order.
fn selections(n: roxmltree::Node) -> Vec<(String, String, u64)> {
    n.children()
        .filter(|c| matches!(c.attribute("class"), Some("took" | "eos")))
        .map(|c| {
            let class = c.attribute("class").unwrap_or("").to_string();
            let a = c.attribute("data-automaton").unwrap_or("").to_string();
            (class, a, ms(c, "data-t"))
        })
        .collect()
}

fn st(s: &str, from: u64, to: u64) -> (String, u64, u64) {
    (s.to_string(), from, to)
}

#[test]
fn the_station_timeline_has_its_lanes_in_order_then_the_charts_and_the_radio() {
    let c = build(&load(SORTER));
    let svg = svg_of(&c, "B O");
    let doc = roxmltree::Document::parse(&svg).expect("the SVG parses");
    assert_eq!(lanes(&doc, "pusher"), ["PUSHER"]);
    assert_eq!(lanes(&doc, "gate"), ["G1", "G2"]);
    assert_eq!(
        lanes(&doc, "sensor"),
        ["CAP", "IND", "OPT", "ENTRY", "BIN1", "BIN2", "BIN3"]
    );
    assert_eq!(lanes(&doc, "ball"), ["ball 1", "ball 2"]);
    assert_eq!(
        lanes(&doc, "chart"),
        [
            "SENSING.feed",
            "SENSING.bins",
            "SENSING.part",
            "GATE1.gate",
            "GATE1.nd.t1",
            "GATE1.nd.t2",
            "GATE1.nd.t3",
            "GATE1.nd.t4",
            "GATE1.nd.t5",
            "GATE2.gate",
            "GATE2.fig1.t1",
            "GATE2.fig1.t2",
            "GATE2.fig1.t3",
            "GATE2.fig1.t4"
        ]
    );
    assert_eq!(lanes(&doc, "radio"), ["radio"]);
    // The station's lanes come first, top down: pusher, gates, sensors, balls, charts.
    let order: Vec<&str> = doc
        .descendants()
        .filter_map(|n| n.attribute("class")?.strip_prefix("lane "))
        .collect();
    let mut kinds = order.clone();
    kinds.dedup();
    assert_eq!(
        kinds,
        ["pusher", "gate", "sensor", "ball", "chart", "radio"]
    );
}

/// B O: both automata take the black ball (bin 1 first); the orange one ends `nd`'s
/// sequence (EOS) and `fig1` (in s1) does not read it: only gate 1 opens for it.
#[test]
fn the_pusher_gates_sensors_and_balls_have_their_exact_intervals_and_marks() {
    let c = build(&load(SORTER));
    let svg = svg_of(&c, "B O");
    let doc = roxmltree::Document::parse(&svg).expect("parses");
    let pusher = lane(&doc, "pusher", "PUSHER");
    assert_eq!(
        states(pusher),
        [
            st("home", 0, 184),
            st("moving", 184, 304),
            st("fed", 304, 334),
            st("moving", 334, 434),
            st("home", 434, 642),
            st("moving", 642, 762),
            st("fed", 762, 792),
            st("moving", 792, 892),
            st("home", 892, 1016),
        ]
    );
    let fed: Vec<u64> = (pusher.children())
        .filter(|n| n.attribute("class") == Some("fed"))
        .map(|n| ms(n, "data-t"))
        .collect();
    assert_eq!(fed, [304, 762]);
    assert_eq!(
        states(lane(&doc, "gate", "G1")),
        [
            st("closed", 0, 102),
            st("opening", 102, 182),
            st("open", 182, 376),
            st("closing", 376, 456),
            st("closed", 456, 560),
            st("opening", 560, 640),
            st("open", 640, 834),
            st("closing", 834, 914),
            st("closed", 914, 1016),
        ]
    );
    assert_eq!(
        states(lane(&doc, "gate", "G2")),
        [
            st("closed", 0, 102),
            st("opening", 102, 182),
            st("open", 182, 376),
            st("closing", 376, 456),
            st("closed", 456, 1016),
        ]
    );
    // black is CAP only, orange CAP and OPT; each drops as the pusher feeds the ball.
    let sensor = |n| spans(lane(&doc, "sensor", n), "high");
    assert_eq!(sensor("CAP"), [(0, 304), (484, 762)]);
    assert_eq!(sensor("IND"), []);
    assert_eq!(sensor("OPT"), [(484, 762)]);
    assert_eq!(sensor("ENTRY"), [(334, 344), (792, 802)]);
    assert_eq!(sensor("BIN1"), [(374, 384), (832, 842)]);
    assert_eq!(sensor("BIN2"), []);
    assert_eq!(sensor("BIN3"), []);
    let b1 = lane(&doc, "ball", "ball 1");
    assert_eq!(
        (
            b1.attribute("data-colour"),
            b1.attribute("data-took"),
            b1.attribute("data-bin")
        ),
        (Some("black"), Some("nd fig1"), Some("1"))
    );
    assert_eq!(spans(b1, "at-sensors"), [(0, 304)]);
    assert_eq!(spans(b1, "falling"), [(304, 374)]);
    assert_eq!(
        selections(b1),
        [
            ("took".into(), "nd".into(), 102),
            ("took".into(), "fig1".into(), 102)
        ]
    );
    let b2 = lane(&doc, "ball", "ball 2");
    assert_eq!(
        (
            b2.attribute("data-colour"),
            b2.attribute("data-took"),
            b2.attribute("data-bin")
        ),
        (Some("orange"), Some("nd"), Some("1"))
    );
    assert_eq!(spans(b2, "at-sensors"), [(484, 762)]);
    assert_eq!(spans(b2, "falling"), [(762, 832)]);
    assert_eq!(
        selections(b2),
        [
            ("took".into(), "nd".into(), 560),
            ("eos".into(), "nd".into(), 560)
        ]
    );
}

/// The whole feed of the robot file: one ball lane per ball with its colour, bin and
/// EOS marks as `sim` prints them.
#[test]
fn every_ball_of_the_feed_has_its_lane_with_the_report_s_bin_and_eos() {
    let c = build(&load(SORTER));
    let run = sorter::simulate(&c, None).expect("runs");
    let svg = station::svg(&c, &run).expect("draws");
    let doc = roxmltree::Document::parse(&svg).expect("parses");
    let balls: Vec<(String, String, String, Vec<String>)> = doc
        .descendants()
        .filter(|n| n.attribute("class") == Some("lane ball"))
        .map(|n| {
            let attr = |a| n.attribute(a).unwrap_or("").to_string();
            let eos = (n.children())
                .filter(|c| c.attribute("class") == Some("eos"))
                .map(|c| c.attribute("data-automaton").unwrap_or("").to_string())
                .collect();
            (
                attr("data-colour"),
                attr("data-took"),
                attr("data-bin"),
                eos,
            )
        })
        .collect();
    let want: Vec<(String, String, String, Vec<String>)> = (run.balls.iter())
        .map(|b| {
            let bin = b.bin.map_or(String::new(), |b| b.to_string());
            (b.colour.clone(), b.took.join(" "), bin, b.eos.clone())
        })
        .collect();
    assert_eq!(balls, want);
    assert_eq!(balls.len(), 13);
    let eos: usize = balls.iter().map(|b| b.3.len()).sum();
    assert_eq!(eos, 8, "{}", run.report());
}

/// A gate that closes as the ball enters the shaft (not once it landed): the ball meets
/// it moving, which its lane marks at that time.
#[test]
fn a_ball_meeting_a_moving_gate_is_marked_on_the_gate_s_lane() {
    let text = load(SORTER).text.replacen(
        r#""LANDED": "SENSING/bins.landed","#,
        r#""LANDED": "SENSING/ENTRY","#,
        1,
    );
    let c = build(&robot_compiler::Source::new("early.ron", text));
    let svg = svg_of(&c, "black");
    let doc = roxmltree::Document::parse(&svg).expect("parses");
    let met = |gate| {
        (lane(&doc, "gate", gate).children())
            .filter(|n| n.attribute("class") == Some("met-moving"))
            .map(|n| (ms(n, "data-t"), ms(n, "data-ball")))
            .collect::<Vec<_>>()
    };
    assert_eq!(met("G1"), [(374, 1)]);
    assert_eq!(met("G2"), []);
    let b1 = lane(&doc, "ball", "ball 1");
    assert_eq!(b1.attribute("data-bin"), Some("2"));
}
