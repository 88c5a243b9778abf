//! The paper's painting robot (SEEDS.md, sequence (1)), hand-built as four tables in the
//! paper's style: events only, no data; position events VC0/VC1, HC0/HC1, RC0/RC1 (the rise
//! of each cylinder's home / end switch) and START; each chart's states count where its
//! actuator is in the cycle, so an event that recurs in the cycle (VC0 three times) only
//! acts in the state that expects it, and is ignored in every other.
//!
//! ```text
//! VC: S0 -START-> S1[VC+] -GR1-> S2[VC-] -HC1-> S3[VC+] -VC1-> S4[VC-] -HC0-> S5[VC+]
//!        -GR0-> S6[VC-] -VC0-> S0
//! GR: S0 -VC1-> S1[close, dwell] -T-> S2[emit GR1] -VC1-> S3 (the dip) -VC1-> S4[open, dwell]
//!        -T-> S0[emit GR0]
//! HC: S0 -VC0-> S1[HC+] -VC0-> S2 -RC0-> S3[HC-] -VC0-> S0
//! RC: S0 -VC0-> S1 -VC0-> S2[RC+] -RC1-> S3[RC-] -VC0-> S0
//! ```
//!
//! GR's `S0[emit GR0]` runs when S0 is entered from S4, never at start-up (an initial
//! state's actions do not run at init). Each bistable valve is driven with one
//! `Drive { mask: EXT | RET, .. }` per motion, so its two solenoids change atomically.
//!
//! Radio: each event goes only to the nodes that use it.
//!
//! | topic | publisher | subscribers |
//! |---|---|---|
//! | VC0 | VC | HC, RC |
//! | VC1 | VC | GR |
//! | GR0, GR1 | GR | VC |
//! | HC0, HC1 | HC | VC |
//! | RC0 | RC | HC |
//!
//! RC1 stays on RC's node.

use config_schema::{
    Action, EventId, Full, Input, Output, Publication, Route, Subscription, Table, Timer, Topic,
    Transition,
};
use node_fw::sim::{Button, DoubleActing, NodeSpec, Plant, SingleActing, World};

/// Sequence (1) of the paper.
pub const SEQUENCE: [&str; 12] = [
    "VC+", "GR+", "VC-", "HC+", "VC+", "VC-", "RC+", "RC-", "HC-", "VC+", "GR-", "VC-",
];

/// The roles, in node order: node `i` plays `ROLES[i]` at address `ADDRS[i]`.
pub const ROLES: [&str; 4] = ["VC", "GR", "HC", "RC"];
/// Short addresses of the four nodes.
pub const ADDRS: [u16; 4] = [0x0011, 0x0012, 0x0013, 0x0014];
/// Node indices.
pub const VC: usize = 0;
pub const GR: usize = 1;
pub const HC: usize = 2;
pub const RC: usize = 3;
/// PAN id and channel of the robot's network.
pub const PAN_ID: u16 = 0x0061;
pub const CHANNEL: u8 = 15;

/// Robot-wide radio topics.
pub mod topic {
    use config_schema::Topic;
    pub const VC0: Topic = 0;
    pub const VC1: Topic = 1;
    pub const GR0: Topic = 2;
    pub const GR1: Topic = 3;
    pub const HC0: Topic = 4;
    pub const HC1: Topic = 5;
    pub const RC0: Topic = 6;
}

/// Bistable valve outputs of a cylinder node: output 0 extends, output 1 retracts.
pub const EXT: u16 = 0b01;
pub const RET: u16 = 0b10;
const PLUS: Action = Action::Drive {
    mask: EXT | RET,
    value: EXT,
};
const MINUS: Action = Action::Drive {
    mask: EXT | RET,
    value: RET,
};

/// The VC table's ids (node events are also the chart's inputs, one route each).
pub mod vc {
    use config_schema::EventId;
    pub const START: EventId = 0;
    pub const VC0: EventId = 1;
    pub const VC1: EventId = 2;
    pub const GR1: EventId = 3;
    pub const HC1: EventId = 4;
    pub const HC0: EventId = 5;
    pub const GR0: EventId = 6;
    /// Inputs: the START button, the home switch, the end switch.
    pub const IN_START: u8 = 0;
    pub const IN_HOME: u8 = 1;
    pub const IN_END: u8 = 2;
    /// Peers (indices into `peers`).
    pub const PEER_GR: u8 = 0;
    pub const PEER_HC: u8 = 1;
    pub const PEER_RC: u8 = 2;
}

/// GR's ids.
pub mod gr {
    use config_schema::EventId;
    pub const VC1: EventId = 0;
    pub const DWELL: EventId = 1;
    pub const GR1: EventId = 2;
    pub const GR0: EventId = 3;
    /// Time the gripper is given to close / open before GR reports it done.
    pub const DWELL_MS: u32 = 150;
}

/// HC's ids.
pub mod hc {
    use config_schema::EventId;
    pub const VC0: EventId = 0;
    pub const RC0: EventId = 1;
    pub const HC0: EventId = 2;
    pub const HC1: EventId = 3;
}

/// RC's ids.
pub mod rc {
    use config_schema::EventId;
    pub const VC0: EventId = 0;
    pub const RC1: EventId = 1;
    pub const RC0: EventId = 2;
}

fn on(from: u8, trigger: u8, to: u8) -> Transition {
    Transition {
        from,
        to,
        trigger: Some(trigger),
        guard: None,
    }
}

fn new_table(role: &str, events: u8) -> Result<Table, Full> {
    let mut t = Table::empty(role);
    t.header.pan_id = PAN_ID;
    t.header.channel = CHANNEL;
    for _ in 0..events {
        t.push_event()?;
    }
    Ok(t)
}

fn push<T, const N: usize>(
    v: &mut heapless::Vec<T, N>,
    x: T,
    what: &'static str,
) -> Result<(), Full> {
    v.push(x).map_err(|_| Full(what))
}

/// An input whose rise raises `rise`.
fn switch(t: &mut Table, pin: u8, rise: EventId) -> Result<(), Full> {
    push(
        &mut t.inputs,
        Input {
            pin,
            rise: Some(rise),
            fall: None,
            var: None,
        },
        "inputs",
    )
}

fn outputs(t: &mut Table, pins: &[u8]) -> Result<(), Full> {
    for &pin in pins {
        push(&mut t.outputs, Output::safe(pin, false), "outputs")?;
    }
    Ok(())
}

/// Routes node event `event` to chart 0's input `input`.
fn route(t: &mut Table, event: EventId, input: u8) -> Result<(), Full> {
    push(
        &mut t.routes,
        Route {
            event,
            chart: 0,
            input,
        },
        "routes",
    )
}

fn publish(t: &mut Table, event: EventId, topic: Topic, subscribers: u8) -> Result<(), Full> {
    push(
        &mut t.publications,
        Publication {
            event,
            topic,
            subscribers,
        },
        "publications",
    )
}

fn subscribe(t: &mut Table, publisher: u8, topic: Topic, event: EventId) -> Result<(), Full> {
    push(
        &mut t.subscriptions,
        Subscription {
            publisher,
            topic,
            event,
        },
        "subscriptions",
    )
}

fn peers(t: &mut Table, nodes: &[usize]) -> Result<(), Full> {
    for &n in nodes {
        push(&mut t.peers, ADDRS[n], "peers")?;
    }
    Ok(())
}

/// The vertical cylinder: the cycle's master, started by START.
pub fn vc_table() -> Result<Table, Full> {
    use vc::*;
    let mut t = new_table("VC", 7)?;
    t.start = Some(START);
    switch(&mut t, 0, START)?;
    switch(&mut t, 1, VC0)?;
    switch(&mut t, 2, VC1)?;
    outputs(&mut t, &[3, 4])?;
    t.push_chart(
        0,
        7,
        &[&[], &[PLUS], &[MINUS], &[PLUS], &[MINUS], &[PLUS], &[MINUS]],
        &[
            on(0, START, 1),
            on(1, GR1, 2),
            on(2, HC1, 3),
            on(3, VC1, 4),
            on(4, HC0, 5),
            on(5, GR0, 6),
            on(6, VC0, 0),
        ],
    )?;
    for event in 0..7 {
        route(&mut t, event, event)?;
    }
    peers(&mut t, &[GR, HC, RC])?;
    publish(&mut t, VC1, topic::VC1, 1 << PEER_GR)?;
    publish(&mut t, VC0, topic::VC0, (1 << PEER_HC) | (1 << PEER_RC))?;
    subscribe(&mut t, PEER_GR, topic::GR1, GR1)?;
    subscribe(&mut t, PEER_GR, topic::GR0, GR0)?;
    subscribe(&mut t, PEER_HC, topic::HC1, HC1)?;
    subscribe(&mut t, PEER_HC, topic::HC0, HC0)?;
    Ok(t)
}

/// The gripper: no sensors, so a dwell timer stands for "closed" / "open".
pub fn gr_table() -> Result<Table, Full> {
    use gr::*;
    let mut t = new_table("GR", 4)?;
    outputs(&mut t, &[3])?;
    push(&mut t.timers, Timer { event: DWELL }, "timers")?;
    let close = Action::Drive { mask: 1, value: 1 };
    let open = Action::Drive { mask: 1, value: 0 };
    let dwell = Action::StartTimer {
        timer: 0,
        ms: DWELL_MS,
    };
    // Chart inputs: 0 = VC1, 1 = the dwell timer.
    t.push_chart(
        0,
        2,
        &[
            &[Action::Emit(GR0)],
            &[close, dwell],
            &[Action::Emit(GR1)],
            &[],
            &[open, dwell],
        ],
        &[
            on(0, 0, 1),
            on(1, 1, 2),
            on(2, 0, 3),
            on(3, 0, 4),
            on(4, 1, 0),
        ],
    )?;
    route(&mut t, VC1, 0)?;
    route(&mut t, DWELL, 1)?;
    peers(&mut t, &[VC])?;
    publish(&mut t, GR1, topic::GR1, 1)?;
    publish(&mut t, GR0, topic::GR0, 1)?;
    subscribe(&mut t, 0, topic::VC1, VC1)?;
    Ok(t)
}

/// The horizontal (rodless) cylinder.
pub fn hc_table() -> Result<Table, Full> {
    use hc::*;
    let mut t = new_table("HC", 4)?;
    switch(&mut t, 1, HC0)?;
    switch(&mut t, 2, HC1)?;
    outputs(&mut t, &[3, 4])?;
    // Chart inputs: 0 = VC0, 1 = RC0.
    t.push_chart(
        0,
        2,
        &[&[], &[PLUS], &[], &[MINUS]],
        &[on(0, 0, 1), on(1, 0, 2), on(2, 1, 3), on(3, 0, 0)],
    )?;
    route(&mut t, VC0, 0)?;
    route(&mut t, RC0, 1)?;
    peers(&mut t, &[VC, RC])?;
    publish(&mut t, HC0, topic::HC0, 1)?;
    publish(&mut t, HC1, topic::HC1, 1)?;
    subscribe(&mut t, 0, topic::VC0, VC0)?;
    subscribe(&mut t, 1, topic::RC0, RC0)?;
    Ok(t)
}

/// The rotary cylinder (the shake).
pub fn rc_table() -> Result<Table, Full> {
    use rc::*;
    let mut t = new_table("RC", 3)?;
    switch(&mut t, 1, RC0)?;
    switch(&mut t, 2, RC1)?;
    outputs(&mut t, &[3, 4])?;
    // Chart inputs: 0 = VC0, 1 = RC1.
    t.push_chart(
        0,
        2,
        &[&[], &[], &[PLUS], &[MINUS]],
        &[on(0, 0, 1), on(1, 0, 2), on(2, 1, 3), on(3, 0, 0)],
    )?;
    route(&mut t, VC0, 0)?;
    route(&mut t, RC1, 1)?;
    peers(&mut t, &[VC, HC])?;
    publish(&mut t, RC0, topic::RC0, 0b10)?;
    subscribe(&mut t, 0, topic::VC0, VC0)?;
    Ok(t)
}

/// The four tables in node order (VC, GR, HC, RC).
pub fn tables() -> Result<[Table; 4], Full> {
    Ok([vc_table()?, gr_table()?, hc_table()?, rc_table()?])
}

/// Plant index of the START button.
pub const START_BUTTON: usize = 0;
/// Plant indices of the actuators.
pub const VC_PLANT: usize = 1;
pub const GR_PLANT: usize = 2;
pub const HC_PLANT: usize = 3;
pub const RC_PLANT: usize = 4;

fn cylinder(name: &str, node: usize, extend_ms: u64, retract_ms: u64) -> Plant {
    DoubleActing {
        name: name.into(),
        node,
        extend_out: 0,
        retract_out: 1,
        home_in: Some(0),
        end_in: Some(1),
        extend_ms,
        retract_ms,
    }
    .into()
}

/// The plant wiring: START on VC's input 0; each cylinder on its node's outputs 0/1 and
/// switch inputs (VC: 1/2, HC and RC: 0/1); the gripper on GR's output 0.
pub fn plants() -> Vec<Plant> {
    let mut vc = cylinder("VC", VC, 250, 250);
    if let Plant::DoubleActing(da) = &mut vc {
        da.home_in = Some(vc::IN_HOME);
        da.end_in = Some(vc::IN_END);
    }
    vec![
        Button::new("START", VC, vc::IN_START).into(),
        vc,
        SingleActing {
            name: "GR".into(),
            node: GR,
            out: 0,
            home_in: None,
            end_in: None,
            extend_ms: 80,
            retract_ms: 80,
        }
        .into(),
        cylinder("HC", HC, 1200, 1200),
        cylinder("RC", RC, 300, 300),
    ]
}

/// The nodes of a world running `tables` (in node order) at [`ADDRS`].
pub fn nodes(tables: &[Table; 4]) -> [NodeSpec<'_>; 4] {
    let spec = |i: usize| NodeSpec {
        addr: ADDRS[i],
        table: &tables[i],
    };
    [spec(0), spec(1), spec(2), spec(3)]
}

/// A world at t = 0 running `tables` with the robot's plants.
pub fn world(tables: &[Table; 4]) -> Result<World<'_>, node_fw::sim::SimError> {
    World::new(&nodes(tables), plants())
}
