//! `push::ask_each`: one command to several nodes at once, each answer taken as its own
//! node's (by address and by the command id it acknowledges), a node that never answers
//! asked again every round and reported with how often.

use std::time::Duration;

use config_schema::wire::msg::{Command, Message};
use robot_net::push::{self, Ids};
use robot_net::radio::{ToolRadio, TOOL_ADDR};

const NODES: [u16; 3] = [0x0021, 0x0022, 0x0023];
/// An address no node has.
const NOBODY: u16 = 0x0024;

#[test]
fn every_node_answers_its_own_command_and_a_missing_one_is_asked_every_round() {
    let medium = medium::Medium::start(medium::Config::default()).expect("medium");
    for addr in NODES {
        let args = node_fw::host::Args {
            addr,
            medium: medium.addr(),
            flash: None,
            key: None,
        };
        // Ends with an error when the medium stops, at the end of the test.
        std::thread::spawn(move || node_fw::host::run(args));
    }
    let mut radio = ToolRadio::connect(medium.addr(), TOOL_ADDR).expect("tool");
    let mut ids = Ids::default();
    // Twice the same node (two roles on one node): each entry its own command.
    let asked = [NODES[1], NOBODY, NODES[0], NODES[1], NODES[2]];
    let answers = push::ask_each(
        &mut radio,
        &mut ids,
        &asked,
        Command::Status,
        Duration::from_secs(2),
        |m, id| match m {
            Message::Status(s) if s.ack == id => Some(s.ack),
            _ => None,
        },
    )
    .expect("radio");
    assert_eq!(answers.len(), asked.len());
    let acks: Vec<u16> = (answers.iter())
        .filter_map(|a| a.as_ref().ok().copied())
        .collect();
    assert_eq!(acks.len(), 4, "{answers:?}");
    let mut distinct = acks.clone();
    distinct.sort_unstable();
    distinct.dedup();
    assert_eq!(distinct.len(), 4, "one id per entry: {answers:?}");
    // Asked once a round (150 ms) for the 2 s the others took at most.
    assert!(
        matches!(answers[1], Err(n) if n >= 2),
        "the missing node: {:?}",
        answers[1]
    );
    medium.stop();
}
