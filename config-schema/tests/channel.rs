//! The radio channel of a table: only the 2.4 GHz IEEE 802.15.4 channels 11..=26, refused
//! by `validate` and so by `decode` (what a node runs and `config-tool dump` shows).

mod common;

use common::{blob, realistic};
use config_schema::limits::CHANNELS;
use config_schema::{decode, validate, DecodeError, Invalid};

#[test]
fn a_channel_outside_11_to_26_is_refused() {
    for channel in [0, 10, 27, 200, 255] {
        let mut t = realistic();
        t.header.channel = channel;
        assert_eq!(validate(&t), Err(Invalid::Channel { channel }));
        assert_eq!(
            decode(&blob(&t)),
            Err(DecodeError::Invalid(Invalid::Channel { channel }))
        );
    }
    assert_eq!(
        Invalid::Channel { channel: 200 }.to_string(),
        "channel 200 is not an IEEE 802.15.4 2.4 GHz channel (11..=26)"
    );
    for channel in CHANNELS {
        let mut t = realistic();
        t.header.channel = channel;
        assert_eq!(validate(&t), Ok(()));
    }
}
