//! The node's own services in a basic FB type: what a chart does besides assigning and
//! emitting (drive an actuator or an output, start or stop a timer, fault the node)
//! written as output events of reserved names, and a timer's expiry as the event input
//! of the timer's name. `export` writes them, the `.fbt` import reads them back, in a
//! type marked as a chart of this project ([`MARK`]) only: elsewhere such names are
//! ordinary events (docs/iec61499-xml.md, "The export").

use crate::model::ActionDecl;

/// The `Classification` of the `Identification` of an FB type whose reserved output
/// events are node services.
pub const MARK: &str = "ecc-nodes chart";

/// The `Classification` of a role's interface-only FB type (`ROLE_IO`) standing for the
/// node's inputs, switches and timers (its event outputs, each `Comment` the node event)
/// and its services (its event inputs, fed by the marked charts' service events).
pub const IO_MARK: &str = "ecc-nodes services";

/// The `Comment` prefix of a marked type's BOOL input variable that stands for the level
/// of one of its role's inputs (`level of VC.home`): a lifted chart reads the level in
/// its guards, and the import reads the input again instead of a parameter.
const LEVEL: &str = "level of ";

/// The `Comment` prefix of a marked type's internal variable that holds a control
/// function's place, by its column (`places of Pusher: Stopped Clockwise
/// CounterClockwise`): the robot's own conditions (alarms) read the function's places
/// (`Pusher.Stopped`) through it again once the function is a lifted chart.
const PLACES: &str = "places of ";

/// The `Comment` prefix of a marked type's input variable that stands for the value of
/// another chart's variable on its role (`value of CABINET_Operation.Operation_state`:
/// the FB of that chart in the application, the variable in its type): a lifted chart
/// reads the variable in its guards and assignments, and the import reads it again
/// (the role's variables are one pool), no parameter.
const VALUE: &str = "value of ";

/// The `Comment` prefix of a `ROLE_IO` event output that is a node event of its own, no
/// pin or timer (`node event boot`): [`NODE_EVENTS`].
const NODE_EVENT: &str = "node event ";

/// The `Comment` of a marked type's `ECState` where the chart rests between cycles, when
/// that is not its first (initial) state.
pub const IDLE: &str = "Idle State";

/// The `Comment` of a marked type's `ECState` where the chart also rests between cycles
/// besides its idle state (a mode kept from one cycle to the next; among its first 32).
pub const REST: &str = "Rest State";

/// The node events a role raises besides its pins, timers and charts' outputs: the
/// node's boot with its table (published to the roles that import it) and the HOME
/// command (the synthesised homing of a sequence robot reads both).
pub const NODE_EVENTS: [&str; 2] = [crate::synth::BOOT_EVENT, crate::synth::HOME_COMMAND_EVENT];

/// The `Comment` of a BOOL input variable reading the level of role input `input`.
pub fn level_comment(input: &str) -> String {
    format!("{LEVEL}{input}")
}

/// The role input whose level a marked type's input variable reads, from its `Comment`.
pub fn level_of(comment: &str) -> Option<&str> {
    comment.trim().strip_prefix(LEVEL).filter(|i| !i.is_empty())
}

/// The `Comment` of an input variable reading variable `var` of FB `fb`.
pub fn value_comment(fb: &str, var: &str) -> String {
    format!("{VALUE}{fb}.{var}")
}

/// The FB and its variable a marked type's input variable reads, from its `Comment`
/// (`value of FB.VAR`; the FB's name may have dots of its own, a composite's FBs'
/// names do, the variable's not).
pub fn value_of(comment: &str) -> Option<(&str, &str)> {
    let (fb, var) = comment.trim().strip_prefix(VALUE)?.rsplit_once('.')?;
    (!fb.is_empty()
        && !var.is_empty()
        && !fb.contains(char::is_whitespace)
        && !var.contains(char::is_whitespace))
    .then_some((fb, var))
}

/// The `Comment` of a variable holding function `function`'s place, of `places` in
/// column order.
pub fn places_comment(function: &str, places: &[String]) -> String {
    format!("{PLACES}{function}: {}", places.join(" "))
}

/// The function and its places (in column order) a marked type's variable holds, from
/// its `Comment`.
pub fn places_of(comment: &str) -> Option<(String, Vec<String>)> {
    let (f, places) = comment.trim().strip_prefix(PLACES)?.split_once(':')?;
    let places: Vec<String> = places.split_whitespace().map(str::to_string).collect();
    let f = f.trim();
    (!f.is_empty() && !places.is_empty()).then(|| (f.to_string(), places))
}

/// The `Comment` of a `ROLE_IO` event output standing for node event `event`: the event
/// itself, or `node event boot` for one of [`NODE_EVENTS`].
pub fn io_comment(event: &str) -> String {
    if NODE_EVENTS.contains(&event) {
        format!("{NODE_EVENT}{event}")
    } else {
        event.to_string()
    }
}

/// The node event of a `ROLE_IO` event output's `Comment`, and whether it is one of
/// [`NODE_EVENTS`] (`node event boot`).
pub fn io_event(comment: &str) -> (&str, bool) {
    match comment.strip_prefix(NODE_EVENT) {
        Some(e) if NODE_EVENTS.contains(&e) => (e, true),
        _ => (comment, false),
    }
}

/// `EXTEND_A`, `RETRACT_A`, `SET_O`, `RESET_O`, `START_T_150` (ms), `STOP_T`, `FAULT_3`.
const PREFIXES: [&str; 7] = [
    "EXTEND_", "RETRACT_", "SET_", "RESET_", "START_", "STOP_", "FAULT_",
];

/// The output event that asks for `action`; none for an assignment or a chart output.
pub fn event(action: &ActionDecl) -> Option<String> {
    Some(match action {
        ActionDecl::Set(..) | ActionDecl::Emit(_) => return None,
        ActionDecl::Extend(a) => format!("EXTEND_{a}"),
        ActionDecl::Retract(a) => format!("RETRACT_{a}"),
        ActionDecl::Out(o, true) => format!("SET_{o}"),
        ActionDecl::Out(o, false) => format!("RESET_{o}"),
        ActionDecl::StartTimer(t, ms) => format!("START_{t}_{ms}"),
        ActionDecl::CancelTimer(t) => format!("STOP_{t}"),
        ActionDecl::Fault(code) => format!("FAULT_{code}"),
    })
}

/// Whether `name` is a reserved service name (of any timer).
pub fn is_reserved(name: &str) -> bool {
    PREFIXES.iter().any(|p| name.starts_with(p))
}

/// The action an output event of a marked type asks for; `timers` are its timers (the
/// event inputs some `START_` or `STOP_` names). `None`: an ordinary output event.
pub fn action(name: &str, timers: &[String]) -> Option<ActionDecl> {
    let rest = |p: &str| name.strip_prefix(p).filter(|r| !r.is_empty());
    if let Some(a) = rest("EXTEND_") {
        return Some(ActionDecl::Extend(a.to_string()));
    }
    if let Some(a) = rest("RETRACT_") {
        return Some(ActionDecl::Retract(a.to_string()));
    }
    if let Some(o) = rest("SET_") {
        return Some(ActionDecl::Out(o.to_string(), true));
    }
    if let Some(o) = rest("RESET_") {
        return Some(ActionDecl::Out(o.to_string(), false));
    }
    if let Some(t) = rest("STOP_").filter(|t| timers.iter().any(|x| x == t)) {
        return Some(ActionDecl::CancelTimer(t.to_string()));
    }
    if let Some((t, ms)) = rest("START_").and_then(|r| r.rsplit_once('_')) {
        if let (true, Ok(ms)) = (timers.iter().any(|x| x == t), ms.parse::<u32>()) {
            return Some(ActionDecl::StartTimer(t.to_string(), ms));
        }
    }
    rest("FAULT_")
        .and_then(|c| c.parse::<u8>().ok())
        .map(ActionDecl::Fault)
}

/// The timers an output event `START_T_MS` or `STOP_T` names, among `inputs`.
pub fn timer_of<'a>(name: &str, inputs: &'a [String]) -> Option<&'a String> {
    let t = match name.strip_prefix("STOP_") {
        Some(t) => t,
        None => name.strip_prefix("START_")?.rsplit_once('_')?.0,
    };
    inputs.iter().find(|i| *i == t)
}

#[cfg(test)]
mod tests {
    use super::{action, event, io_comment, io_event, level_comment, level_of, timer_of};
    use crate::model::ActionDecl;

    /// Every service action goes to its event name and back; ordinary names stay events.
    #[test]
    fn service_events_round_trip() {
        let timers = vec![String::from("T"), String::from("WATCH_DOG")];
        for a in [
            ActionDecl::Extend(String::from("VC")),
            ActionDecl::Retract(String::from("GR")),
            ActionDecl::Out(String::from("AUTO_LAMP"), true),
            ActionDecl::Out(String::from("AUTO_LAMP"), false),
            ActionDecl::StartTimer(String::from("T"), 150),
            ActionDecl::StartTimer(String::from("WATCH_DOG"), 2000),
            ActionDecl::CancelTimer(String::from("WATCH_DOG")),
            ActionDecl::Fault(3),
        ] {
            let e = event(&a).unwrap();
            assert_eq!(action(&e, &timers), Some(a), "{e}");
        }
        assert_eq!(event(&ActionDecl::Emit(String::from("X"))), None);
        assert_eq!(action("EO", &timers), None);
        assert_eq!(action("START_X_5", &timers), None, "not a timer");
        assert_eq!(action("FAULT_300", &timers), None, "not a code");
        let inputs = vec![String::from("CU"), String::from("WATCH_DOG")];
        assert_eq!(timer_of("START_WATCH_DOG_20", &inputs), Some(&inputs[1]));
        assert_eq!(timer_of("STOP_CU", &inputs), Some(&inputs[0]));
        assert_eq!(timer_of("EO", &inputs), None);
    }

    /// Input levels and node events go to their comments and back; other comments are
    /// what they say.
    #[test]
    fn levels_and_node_events_round_trip() {
        assert_eq!(level_comment("VC.home"), "level of VC.home");
        assert_eq!(level_of("level of VC.home"), Some("VC.home"));
        assert_eq!(level_of("level of "), None);
        assert_eq!(level_of(""), None);
        assert_eq!(io_comment("boot"), "node event boot");
        assert_eq!(io_event("node event boot"), ("boot", true));
        assert_eq!(io_comment("home"), "node event home");
        assert_eq!(io_event("node event home"), ("home", true));
        assert_eq!(io_comment("VC.home"), "VC.home");
        assert_eq!(io_event("VC.home"), ("VC.home", false));
        assert_eq!(io_event("home"), ("home", false), "an input named `home`");
        assert_eq!(io_event("node event x"), ("node event x", false));
    }

    /// Another chart's variable goes to an input variable's comment and back.
    #[test]
    fn values_round_trip() {
        use super::{value_comment, value_of};
        let c = value_comment("CABINET_Operation", "Operation_state");
        assert_eq!(c, "value of CABINET_Operation.Operation_state");
        assert_eq!(value_of(&c), Some(("CABINET_Operation", "Operation_state")));
        assert_eq!(value_of("value of k.c.CV"), Some(("k.c", "CV")));
        assert_eq!(value_of("value of CV"), None);
        assert_eq!(value_of("value of .CV"), None);
        assert_eq!(value_of("value of c."), None);
        assert_eq!(value_of("value of a b.c"), None);
        assert_eq!(value_of("level of VC.home"), None);
    }

    /// A function's places go to a variable's comment and back.
    #[test]
    fn places_round_trip() {
        use super::{places_comment, places_of};
        let places = vec![String::from("Ok"), String::from("Faulted")];
        let c = places_comment("FaultDetection", &places);
        assert_eq!(c, "places of FaultDetection: Ok Faulted");
        assert_eq!(
            places_of(&c),
            Some((String::from("FaultDetection"), places))
        );
        assert_eq!(places_of("places of F:"), None);
        assert_eq!(places_of("places of : A"), None);
        assert_eq!(places_of("the places"), None);
    }
}
