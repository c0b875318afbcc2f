//! An input as a station sent it: its media type and bytes, kept byte for
//! byte with the record it becomes.

use bytes::Bytes;

use crate::domain::submission::Media;

/// A submitted body with its media type.
#[derive(Debug)]
pub struct Upload {
    /// Its media type.
    pub media: Media,
    /// Its bytes (decompressed, when it was sent compressed).
    pub bytes: Bytes,
    /// The `Content-Type` as sent (stored with submissions).
    pub content_type: String,
}

impl Upload {
    /// A stored submission read again as the input it was (for
    /// reprocessing): its media type from its stored `Content-Type`, which
    /// was accepted when it was received (`text/csv` with at most a UTF-8
    /// charset, else JSON).
    pub fn stored(content_type: String, bytes: Bytes) -> Upload {
        let essence = content_type
            .split(';')
            .next()
            .unwrap_or_default()
            .trim()
            .to_ascii_lowercase();
        let media = if essence == "text/csv" {
            Media::Csv
        } else {
            Media::Json
        };
        Upload {
            media,
            bytes,
            content_type,
        }
    }
}
