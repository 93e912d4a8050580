//! Fuzzes the YAML front end: any input must give `Ok` or a located `Err`,
//! never a panic (libfuzzer aborts on one, including inside the parser
//! thread), a hang or unbounded memory. A panic that the parser thread
//! catches and turns into "internal error" is reported as a crash too.
#![no_main]

use libfuzzer_sys::fuzz_target;

/// The parsers run on a thread and turn a panic into exactly these errors
/// (line 0). Compare exactly: inputs may echo "internal error" into messages.
fn is_caught_panic(e: &btrel::tree::TreeError) -> bool {
    e.line == 0
        && (e.message == "internal error: the parser panicked"
            || e.message == "internal error: the XML parser panicked")
}

fuzz_target!(|data: &[u8]| {
    let Ok(text) = std::str::from_utf8(data) else {
        return;
    };
    if let Err(e) = btrel::tree::parse_str(text, "fuzz.yaml") {
        assert!(!is_caught_panic(&e), "parser panicked: {e}");
        // every error must render (caret line, help) without panicking
        let _ = e.to_string();
    }
});
