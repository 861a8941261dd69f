//! The error of the DDS link's construction: a participant, node, topic, reader or writer
//! that could not be made ([`DdsError`]).

/// Why the DDS link (or one of its topics) could not start: the text names what failed
/// (`"DDS participant: ..."`, `"pose: ..."`).
#[derive(Debug)]
pub struct DdsError(pub String);

impl std::fmt::Display for DdsError {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str(&self.0)
    }
}

impl std::error::Error for DdsError {}

/// A `map_err` that names `what` failed, with the cause's debug text.
pub(crate) fn err<E: std::fmt::Debug>(what: &str) -> impl FnOnce(E) -> DdsError + '_ {
    move |e| DdsError(format!("{what}: {e:?}"))
}
