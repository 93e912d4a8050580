//! Fuzzes the BehaviorTree.CPP XML front end. The input is split at the
//! first NUL byte: the XML text before it, the params YAML after it (no NUL:
//! the bundled search-and-grasp parameters), so both files are exercised.
#![no_main]

use libfuzzer_sys::fuzz_target;

const PARAMS: &str = include_str!("../../trees/search-and-grasp.params.yaml");

/// The parsers run on a thread and turn a panic into exactly these errors
/// (line 0). Compare exactly: inputs may echo "internal error" into messages.
fn is_caught_panic(e: &btrel::tree::TreeError) -> bool {
    e.line == 0
        && (e.message == "internal error: the parser panicked"
            || e.message == "internal error: the XML parser panicked")
}

fuzz_target!(|data: &[u8]| {
    let (xml, params) = match data.iter().position(|&b| b == 0) {
        Some(i) => (&data[..i], &data[i + 1..]),
        None => (data, PARAMS.as_bytes()),
    };
    let (Ok(xml), Ok(params)) = (std::str::from_utf8(xml), std::str::from_utf8(params)) else {
        return;
    };
    if let Err(e) = btrel::tree::xml::parse_xml_str(xml, "fuzz.xml", params, "fuzz.params.yaml") {
        assert!(!is_caught_panic(&e), "parser panicked: {e}");
        let _ = e.to_string();
    }
});
