//! Tiny ULog files written by hand in the ULog binary format: the file header and the message
//! framing (definitions, subscriptions and data are the caller's payloads).

/// The file header: magic, version 1, start timestamp (us), then the flag bits message
/// (compat, incompat and appended offsets all clear).
pub fn header(start_us: u64) -> Vec<u8> {
    let mut f = b"ULog\x01\x12\x35".to_vec();
    f.push(1);
    f.extend_from_slice(&start_us.to_le_bytes());
    msg(&mut f, b'B', &[0u8; 40]);
    f
}

/// One message: size (u16, little endian), type, payload.
pub fn msg(out: &mut Vec<u8>, kind: u8, payload: &[u8]) {
    out.extend_from_slice(&(payload.len() as u16).to_le_bytes());
    out.push(kind);
    out.extend_from_slice(payload);
}

/// An `add_logged` message: multi id 0, `msg_id`, the topic's `name`.
pub fn add_logged(out: &mut Vec<u8>, msg_id: u16, name: &str) {
    add_logged_instance(out, 0, msg_id, name);
}

/// An `add_logged` message for instance `multi_id` of the topic `name` (several instances of
/// one topic, each under its own `msg_id`).
pub fn add_logged_instance(out: &mut Vec<u8>, multi_id: u8, msg_id: u16, name: &str) {
    let mut a = vec![multi_id];
    a.extend_from_slice(&msg_id.to_le_bytes());
    a.extend_from_slice(name.as_bytes());
    msg(out, b'A', &a);
}
