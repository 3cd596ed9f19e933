//! Reading back an in-memory recording (tests).

use super::rerun_error;
use crate::error::Result;

/// The messages of an in-memory recording ([`RerunRecorder::to_memory`](super::RerunRecorder::to_memory)).
pub struct MemoryRecording {
    pub(super) storage: re_sdk::sink::MemorySinkStorage,
}

/// What an in-memory recording holds for one entity path.
#[derive(Debug, Clone, Default, PartialEq, Eq)]
pub struct EntityRows {
    /// Rows logged on the `iteration` timeline (one per log call).
    pub temporal: usize,
    /// Static rows.
    pub static_rows: usize,
}

impl MemoryRecording {
    /// Takes the messages logged so far (flush the recorder first, [`RerunRecorder::flush`](super::RerunRecorder::flush))
    /// and counts the rows of every entity path of the recording (the blueprint is left out).
    pub fn entity_rows(&self) -> Result<std::collections::BTreeMap<String, EntityRows>> {
        let mut rows = std::collections::BTreeMap::<String, EntityRows>::new();
        for msg in self.storage.take() {
            let re_sdk::log::LogMsg::ArrowMsg(store, arrow) = msg else {
                continue;
            };
            if store.kind() != re_sdk::StoreKind::Recording {
                continue;
            }
            let chunk = re_sdk::log::Chunk::from_arrow_msg(&arrow).map_err(rerun_error)?;
            let path = chunk.entity_path().to_string();
            let path = path.trim_start_matches('/').to_string();
            let entry = rows.entry(path).or_default();
            if chunk.is_static() {
                entry.static_rows += chunk.num_rows();
            } else if chunk.timelines().keys().any(|t| t.as_str() == "iteration") {
                entry.temporal += chunk.num_rows();
            }
        }
        Ok(rows)
    }

    /// Encodes the messages logged so far as the bytes of an `.rrd` file (taking them).
    pub fn rrd_bytes(&self) -> Result<Vec<u8>> {
        self.storage.drain_as_bytes().map_err(rerun_error)
    }
}
