//! The emergency stop in `verify` (docs/verification.md, "The e-stop"): pressing it is a
//! move at any time of the cycle; then the e-stop node must fault in the engine step that
//! sensed it and publish its `estop` to every other node directly, each node must fault in
//! the engine step that receives that publication (one hop, no relay through a third
//! node), and no node the e-stop has reached may command a motion.

use config_schema::{Table, Topic};

use robot_compiler::alarms::ESTOP_EVENT;
use robot_compiler::compile::Compiled;

/// Where the e-stop is and what it publishes.
#[derive(Debug, Clone)]
pub(super) struct EStop {
    /// The node with the e-stop input, and the input.
    pub node: usize,
    pub input: u8,
    /// The topic of its `estop` publication, if its table publishes one.
    pub topic: Option<Topic>,
}

impl EStop {
    /// The robot's e-stop (the first role that has one), from its table.
    pub fn new(c: &Compiled, tables: &[Table]) -> Option<EStop> {
        let (node, input) = (tables.iter().enumerate())
            .find_map(|(i, t)| t.safety.estop.map(|input| (i, input)))?;
        let event = (c.ir.roles.get(node)?.events.iter()).position(|e| e == ESTOP_EVENT);
        let topic = event.and_then(|e| {
            (tables[node].publications.iter())
                .find(|p| usize::from(p.event) == e)
                .map(|p| p.topic)
        });
        Some(EStop { node, input, topic })
    }

    /// The role and input, as the report names them (`VC/ESTOP`).
    pub fn name(&self, c: &Compiled) -> String {
        let r = &c.ir.roles[self.node];
        let input = r.inputs.get(usize::from(self.input));
        format!("{}/{}", r.name, input.map_or("?", |i| i.name.as_str()))
    }

    /// Right after the press: the e-stop node faulted, and its `estop` in flight to every
    /// other node; else what is wrong. `flight` is the model's (link `from * n + to`,
    /// topic) list.
    pub fn after_press(
        &self,
        c: &Compiled,
        faulted: &[bool],
        flight: &[(u8, Topic)],
    ) -> Option<String> {
        let roles = &c.ir.roles;
        let me = &roles[self.node].name;
        if !faulted[self.node] {
            return Some(format!(
                "{me} did not fault in the engine step that sensed its e-stop"
            ));
        }
        let n = faulted.len();
        for (t, r) in roles.iter().enumerate().filter(|(t, _)| *t != self.node) {
            let link = (self.node * n + t) as u8;
            let sent = self
                .topic
                .is_some_and(|topic| flight.contains(&(link, topic)));
            if !sent {
                return Some(format!(
                    "the e-stop does not reach {} in one hop: {me} publishes no `{ESTOP_EVENT}` \
                     to it",
                    r.name
                ));
            }
        }
        None
    }
}
