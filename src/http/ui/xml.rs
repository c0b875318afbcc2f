//! An XML document written through `quick-xml`'s writer, which escapes every
//! text node and attribute value (`<`, `>`, `&`, `'`, `"`, and `\r`, which
//! XML's end-of-line handling would otherwise turn into `\n`).
//!
//! Escaping cannot help a character XML 1.0 has no place for: its `Char`
//! production is `#x9 | #xA | #xD | [#x20-#xD7FF] | [#xE000-#xFFFD] |
//! [#x10000-#x10FFFF]`, so the other C0 controls, U+FFFE and U+FFFF cannot
//! appear even as character references. Input refuses them
//! ([`crate::domain::text::check_str`]), so they reach a document only from
//! data stored before that check; [`Xml`] replaces each with U+FFFD
//! (the replacement character) rather than write a document no parser reads.

use std::borrow::Cow;

use quick_xml::Writer;
use quick_xml::events::{BytesDecl, BytesEnd, BytesStart, BytesText, Event};

/// Whether XML 1.0 can carry `c` (its `Char` production; Rust's `char`
/// excludes the surrogates already).
pub fn is_xml_char(c: char) -> bool {
    matches!(c, '\t' | '\n' | '\r') || (c >= ' ' && !matches!(c, '\u{fffe}' | '\u{ffff}'))
}

/// `text` with every character XML 1.0 cannot carry replaced by U+FFFD;
/// borrowed when there is none (the rule for input).
pub fn char_safe(text: &str) -> Cow<'_, str> {
    if text.chars().all(is_xml_char) {
        Cow::Borrowed(text)
    } else {
        Cow::Owned(
            text.chars()
                .map(|c| if is_xml_char(c) { c } else { '\u{fffd}' })
                .collect(),
        )
    }
}

/// An XML document being written, element by element.
pub struct Xml {
    /// The writer, into memory.
    w: Writer<Vec<u8>>,
}

impl Xml {
    /// A document starting with its declaration (XML 1.0, UTF-8).
    pub fn document() -> Self {
        let mut x = Xml {
            w: Writer::new(Vec::new()),
        };
        x.event(Event::Decl(BytesDecl::new("1.0", Some("UTF-8"), None)));
        x.event(Event::Text(BytesText::new("\n")));
        x
    }

    /// Writes one event. Writing into memory cannot fail (`Vec<u8>`'s
    /// `io::Write` never errs), so an error is a broken invariant.
    fn event(&mut self, e: Event<'_>) {
        self.w
            .write_event(e)
            .expect("writing XML into memory cannot fail");
    }

    /// Element `name` with attributes `attrs` (escaped), its content
    /// written by `inner`.
    pub fn el_attrs(&mut self, name: &str, attrs: &[(&str, &str)], inner: impl FnOnce(&mut Self)) {
        let mut start = BytesStart::new(name);
        for (k, v) in attrs {
            start.push_attribute((*k, char_safe(v).as_ref()));
        }
        self.event(Event::Start(start));
        inner(self);
        self.event(Event::End(BytesEnd::new(name)));
    }

    /// Element `name`, its content written by `inner`.
    pub fn el(&mut self, name: &str, inner: impl FnOnce(&mut Self)) {
        self.el_attrs(name, &[], inner);
    }

    /// Text at the current position, escaped.
    pub fn chars(&mut self, text: &str) {
        self.event(Event::Text(BytesText::new(&char_safe(text))));
    }

    /// Element `name` holding `text` only.
    pub fn text(&mut self, name: &str, text: impl AsRef<str>) {
        self.el(name, |x| x.chars(text.as_ref()));
    }

    /// The document written.
    pub fn finish(self) -> String {
        // Every byte came from a `&str` or an ASCII escape: valid UTF-8.
        String::from_utf8_lossy(&self.w.into_inner()).into_owned()
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn xml_chars_are_those_of_the_production() {
        for c in [
            '\t',
            '\n',
            '\r',
            ' ',
            '\u{d7ff}',
            '\u{e000}',
            '\u{fffd}',
            '\u{10000}',
            '\u{10ffff}',
        ] {
            assert!(is_xml_char(c), "{:?}", c);
        }
        for c in [
            '\0', '\u{8}', '\u{b}', '\u{c}', '\u{e}', '\u{1f}', '\u{fffe}', '\u{ffff}',
        ] {
            assert!(!is_xml_char(c), "{:?}", c);
        }
    }

    #[test]
    fn text_and_attributes_are_escaped_and_only_non_chars_replaced() {
        let mut x = Xml::document();
        x.el_attrs("a:root", &[("lang", "\"en\" & <fr>")], |x| {
            x.text("a:t", "</a:t><x y='1'>&amp;\r\u{fffe}é\u{1}");
        });
        let s = x.finish();
        assert_eq!(
            s,
            "<?xml version=\"1.0\" encoding=\"UTF-8\"?>\n<a:root lang=\"&quot;en&quot; &amp; &lt;fr&gt;\">\
             <a:t>&lt;/a:t&gt;&lt;x y=&apos;1&apos;&gt;&amp;amp;&#13;\u{fffd}é\u{fffd}</a:t></a:root>"
        );
        assert!(matches!(char_safe("plain ünïcode"), Cow::Borrowed(_)));
    }
}
