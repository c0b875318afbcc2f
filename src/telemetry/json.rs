//! JSON log lines, written straight into the line as the fields are
//! visited:
//!
//! ```text
//! {"timestamp":"2026-11-23T17:57:06.246889Z","level":"INFO","message":"request",
//!  "status":200,"latency_ms":0.833,"target":"accelcal::http::stack",
//!  "span":{"request_id":"01a2…","method":"GET","route":"/v1/sensors","path":"/v1/sensors","name":"request"}}
//! ```
//!
//! (one line). The event's fields are flattened into the object, and the
//! span it happened in (a request's) is `span`, with its fields and name.
//! This is the layout of `tracing-subscriber`'s JSON format with
//! `flatten_event` and the current span; that format gathers every field
//! into a map of JSON values, and stores a span's fields as JSON text that
//! it parses back for every line. Here a span's fields are kept as a
//! ready fragment (`"k":v,"k2":v2`) and copied in. Kept because it pays:
//! with `tracing-subscriber`'s own JSON format in its place, a coefficients
//! read at `info` took 107 100 instructions instead of 79 400 (+35 %,
//! callgrind, `benches/instructions.sh`).
//!
//! Strings are escaped as JSON requires (`"`, `\`, and every control
//! character); integers and booleans are written as JSON numbers and
//! booleans; a float is a number when finite and `null` otherwise; any
//! other value is its `Display` or `Debug` text, as a string.

use std::fmt::{self, Write};

use tracing::field::{Field, Visit};
use tracing::{Event, Subscriber};
use tracing_subscriber::fmt::format::Writer;
use tracing_subscriber::fmt::time::{FormatTime, SystemTime};
use tracing_subscriber::fmt::{FmtContext, FormatEvent, FormatFields, FormattedFields};
use tracing_subscriber::registry::LookupSpan;

/// The event format: one JSON object per line.
#[derive(Clone, Copy, Debug, Default)]
pub struct JsonLine;

/// The field format: a span's fields as a JSON fragment, `"k":v,"k2":v2`.
#[derive(Clone, Copy, Debug, Default)]
pub struct JsonFields;

impl<'writer> FormatFields<'writer> for JsonFields {
    fn format_fields<R: tracing_subscriber::field::RecordFields>(
        &self,
        mut writer: Writer<'writer>,
        fields: R,
    ) -> fmt::Result {
        let mut visitor = Fields::new(&mut writer, true);
        fields.record(&mut visitor);
        visitor.result
    }

    fn add_fields(
        &self,
        current: &'writer mut FormattedFields<Self>,
        fields: &tracing::span::Record<'_>,
    ) -> fmt::Result {
        let first = current.fields.is_empty();
        let mut writer = current.as_writer();
        let mut visitor = Fields::new(&mut writer, first);
        fields.record(&mut visitor);
        visitor.result
    }
}

impl<S> FormatEvent<S, JsonFields> for JsonLine
where
    S: Subscriber + for<'a> LookupSpan<'a>,
{
    fn format_event(
        &self,
        ctx: &FmtContext<'_, S, JsonFields>,
        mut w: Writer<'_>,
        event: &Event<'_>,
    ) -> fmt::Result {
        let meta = event.metadata();
        w.write_str("{\"timestamp\":\"")?;
        SystemTime.format_time(&mut w)?;
        write!(w, "\",\"level\":\"{}\"", meta.level())?;
        let mut fields = Fields::new(&mut w, false);
        event.record(&mut fields);
        fields.result?;
        w.write_str(",\"target\":")?;
        string(&mut w, meta.target())?;
        if let Some(span) = ctx.parent_span() {
            w.write_str(",\"span\":{")?;
            let extensions = span.extensions();
            if let Some(f) = extensions.get::<FormattedFields<JsonFields>>()
                && !f.fields.is_empty()
            {
                w.write_str(&f.fields)?;
                w.write_char(',')?;
            }
            w.write_str("\"name\":")?;
            string(&mut w, span.name())?;
            w.write_char('}')?;
        }
        w.write_str("}\n")
    }
}

/// Writes each visited field as `"name":value`, separated by commas (and
/// preceded by one unless it is the first of a fragment).
struct Fields<'a, W: Write> {
    w: &'a mut W,
    first: bool,
    result: fmt::Result,
}

impl<'a, W: Write> Fields<'a, W> {
    fn new(w: &'a mut W, first: bool) -> Self {
        Fields {
            w,
            first,
            result: Ok(()),
        }
    }

    /// Writes the separator and key, then the value with `value`.
    fn field(&mut self, field: &Field, value: impl FnOnce(&mut W) -> fmt::Result) {
        if self.result.is_err() {
            return;
        }
        let separator = if std::mem::take(&mut self.first) {
            ""
        } else {
            ","
        };
        self.result = self
            .w
            .write_str(separator)
            .and_then(|()| string(self.w, field.name()))
            .and_then(|()| self.w.write_char(':'))
            .and_then(|()| value(self.w));
    }
}

impl<W: Write> Visit for Fields<'_, W> {
    fn record_f64(&mut self, field: &Field, value: f64) {
        self.field(field, |w| {
            if value.is_finite() {
                write!(w, "{value}")
            } else {
                w.write_str("null")
            }
        });
    }

    fn record_i64(&mut self, field: &Field, value: i64) {
        self.field(field, |w| write!(w, "{value}"));
    }

    fn record_u64(&mut self, field: &Field, value: u64) {
        self.field(field, |w| write!(w, "{value}"));
    }

    fn record_i128(&mut self, field: &Field, value: i128) {
        self.field(field, |w| write!(w, "{value}"));
    }

    fn record_u128(&mut self, field: &Field, value: u128) {
        self.field(field, |w| write!(w, "{value}"));
    }

    fn record_bool(&mut self, field: &Field, value: bool) {
        self.field(field, |w| write!(w, "{value}"));
    }

    fn record_str(&mut self, field: &Field, value: &str) {
        self.field(field, |w| string(w, value));
    }

    fn record_debug(&mut self, field: &Field, value: &dyn fmt::Debug) {
        self.field(field, |w| {
            w.write_char('"')?;
            write!(Escaped(w), "{value:?}")?;
            w.write_char('"')
        });
    }
}

/// `s` as a JSON string.
fn string<W: Write>(w: &mut W, s: &str) -> fmt::Result {
    w.write_char('"')?;
    Escaped(w).write_str(s)?;
    w.write_char('"')
}

/// Escapes what passes through it for the inside of a JSON string.
struct Escaped<'a, W: Write>(&'a mut W);

impl<W: Write> Write for Escaped<'_, W> {
    fn write_str(&mut self, s: &str) -> fmt::Result {
        let mut clean = 0;
        for (i, byte) in s.bytes().enumerate() {
            let escape = match byte {
                b'"' => "\\\"",
                b'\\' => "\\\\",
                b'\n' => "\\n",
                b'\r' => "\\r",
                b'\t' => "\\t",
                0..=0x1f => "",
                _ => continue,
            };
            self.0.write_str(&s[clean..i])?;
            if escape.is_empty() {
                write!(self.0, "\\u{byte:04x}")?;
            } else {
                self.0.write_str(escape)?;
            }
            clean = i + 1;
        }
        self.0.write_str(&s[clean..])
    }
}

#[cfg(test)]
mod tests {
    use std::sync::{Arc, Mutex};

    use proptest::prelude::*;
    use serde_json::{Value, json};

    use super::*;

    /// The lines a subscriber with this format writes while `f` runs.
    fn lines(f: impl FnOnce()) -> Vec<Value> {
        let out = Arc::new(Mutex::new(Vec::<u8>::new()));
        let sink = out.clone();
        let subscriber = tracing_subscriber::fmt()
            .with_writer(move || Sink(sink.clone()))
            .fmt_fields(JsonFields)
            .event_format(JsonLine)
            .finish();
        tracing::subscriber::with_default(subscriber, f);
        let text = String::from_utf8(out.lock().unwrap().clone()).unwrap();
        assert!(text.ends_with('\n'), "{text}");
        text.lines()
            .map(|l| serde_json::from_str(l).unwrap_or_else(|e| panic!("{e}: {l}")))
            .collect()
    }

    struct Sink(Arc<Mutex<Vec<u8>>>);

    impl std::io::Write for Sink {
        fn write(&mut self, buf: &[u8]) -> std::io::Result<usize> {
            self.0.lock().unwrap().extend_from_slice(buf);
            Ok(buf.len())
        }
        fn flush(&mut self) -> std::io::Result<()> {
            Ok(())
        }
    }

    /// Everything but the timestamp, which is checked on its own.
    fn without_time(mut v: Value) -> Value {
        let t = v["timestamp"].as_str().unwrap().to_owned();
        assert!(
            t.len() == 27 && t.ends_with('Z') && t.as_bytes()[10] == b'T',
            "{t}"
        );
        v.as_object_mut().unwrap().remove("timestamp");
        v
    }

    #[test]
    fn an_event_in_a_span_is_one_object_with_the_span_inside() {
        let got = lines(|| {
            let span = tracing::info_span!(
                "request",
                request_id = %"01a2-x",
                method = %"GET",
                route = "/v1/sensors/{sensor_id}",
            );
            let _entered = span.enter();
            tracing::info!(status = 200u16, latency_ms = 0.833, "request");
            tracing::warn!(
                negative = -3i64,
                ok = true,
                big = 300u128,
                nan = f64::NAN,
                infinite = f64::INFINITY,
                error = %"a \"quoted\"\nline",
                debugged = ?Some("x"),
                "something {} happened",
                "odd"
            );
        });
        let got: Vec<Value> = got.into_iter().map(without_time).collect();
        let span = json!({
            "request_id": "01a2-x",
            "method": "GET",
            "route": "/v1/sensors/{sensor_id}",
            "name": "request",
        });
        let target = module_path!();
        assert_eq!(
            got,
            [
                json!({
                    "level": "INFO", "message": "request", "status": 200,
                    "latency_ms": 0.833, "target": target, "span": span,
                }),
                json!({
                    "level": "WARN", "message": "something odd happened",
                    "negative": -3, "ok": true, "big": 300,
                    "nan": null, "infinite": null, "error": "a \"quoted\"\nline",
                    "debugged": "Some(\"x\")", "target": target, "span": span,
                }),
            ]
        );
    }

    #[test]
    fn an_event_outside_spans_has_no_span_and_fields_recorded_later_are_kept() {
        let got = lines(|| {
            tracing::error!("alone");
            let span = tracing::info_span!("work", first = 1, later = tracing::field::Empty);
            span.record("later", "filled");
            let empty = tracing::info_span!("quiet");
            span.in_scope(|| tracing::info!("inside"));
            empty.in_scope(|| tracing::info!("inside quiet"));
        });
        let got: Vec<Value> = got.into_iter().map(without_time).collect();
        assert_eq!(
            got[0],
            json!({"level": "ERROR", "message": "alone", "target": module_path!()})
        );
        assert_eq!(
            got[1]["span"],
            json!({"first": 1, "later": "filled", "name": "work"})
        );
        assert_eq!(got[2]["span"], json!({"name": "quiet"}));
    }

    /// Every ASCII character, the control characters included, is escaped
    /// as JSON requires and comes back exactly.
    #[test]
    fn every_ascii_character_round_trips() {
        let text: String = (0u8..0x80).map(char::from).collect();
        let got = lines(|| tracing::info!(field = %text, "{}", text));
        assert_eq!(got[0]["field"].as_str(), Some(text.as_str()));
        assert_eq!(got[0]["message"].as_str(), Some(text.as_str()));
    }

    proptest! {
        /// Any text — quotes, backslashes, control characters, any
        /// Unicode — comes back exactly from the line, as a message, a
        /// field and a span's field.
        #[test]
        fn any_text_round_trips(text in prop_oneof![any::<String>(), "[\\x00-\\x7f]{0,64}"]) {
            let got = lines(|| {
                let span = tracing::info_span!("s", text = %text);
                span.in_scope(|| tracing::info!(field = %text, "{}", text));
            });
            prop_assert_eq!(got.len(), 1);
            prop_assert_eq!(got[0]["message"].as_str(), Some(text.as_str()));
            prop_assert_eq!(got[0]["field"].as_str(), Some(text.as_str()));
            prop_assert_eq!(got[0]["span"]["text"].as_str(), Some(text.as_str()));
        }
    }
}
