//! CLIP's text tokenisation: the text clean-up of OpenAI's
//! `simple_tokenizer.py` followed by byte-level BPE with CLIP's 49,408-token
//! vocabulary (bundled by the `instant-clip-tokenizer` crate).
//!
//! CLIP cleans text with `ftfy.fix_text`, `html.unescape` twice and
//! whitespace collapsing before lower-casing. We reproduce the parts of
//! ftfy that change ordinary prompts: NFC normalisation, curly quotes to
//! straight, Latin ligatures and full-width forms expanded, control
//! characters removed; and HTML's character references (numeric ones and
//! the common named ones). Not reproduced: ftfy's mojibake repair (text that
//! was decoded with the wrong codec) and the rarer HTML entity names; such
//! input may tokenise differently from Python's.

use unicode_normalization::UnicodeNormalization;

/// Token sequence length of every CLIP text tower.
pub const CONTEXT_LENGTH: usize = 77;

/// CLIP's BPE tokeniser. Building it parses the 49k merge rules (a few
/// tens of milliseconds): build once, reuse.
pub struct ClipTokenizer {
    inner: instant_clip_tokenizer::Tokenizer,
}

impl Default for ClipTokenizer {
    fn default() -> Self {
        Self::new()
    }
}

impl ClipTokenizer {
    /// The tokeniser with OpenAI CLIP's vocabulary.
    pub fn new() -> ClipTokenizer {
        ClipTokenizer {
            inner: instant_clip_tokenizer::Tokenizer::new(),
        }
    }

    /// Token id of `<|startoftext|>` (49406).
    pub fn start_of_text(&self) -> u32 {
        u32::from(self.inner.start_of_text().to_u16())
    }

    /// Token id of `<|endoftext|>` (49407).
    pub fn end_of_text(&self) -> u32 {
        u32::from(self.inner.end_of_text().to_u16())
    }

    /// BPE token ids of `text` after CLIP's clean-up, without the start and
    /// end markers (CLIP's `Tokenizer.encode`).
    pub fn encode(&self, text: &str) -> Vec<u32> {
        let cleaned = clean(text);
        let mut tokens = Vec::new();
        self.inner.encode(&cleaned, &mut tokens);
        tokens.into_iter().map(|t| u32::from(t.to_u16())).collect()
    }

    /// The model input for `text`: start marker, tokens, end marker, zero
    /// padding to `context_length` (CLIP's `tokenize(..., truncate=True)`:
    /// over-long text keeps its first `context_length - 1` tokens and ends
    /// with the end marker). Returns the ids and whether text was cut.
    pub fn tokenize(&self, text: &str, context_length: usize) -> (Vec<u32>, bool) {
        let context_length = context_length.max(2);
        let mut ids = Vec::with_capacity(context_length);
        ids.push(self.start_of_text());
        ids.extend(self.encode(text));
        ids.push(self.end_of_text());
        let truncated = ids.len() > context_length;
        if truncated {
            ids.truncate(context_length);
            ids[context_length - 1] = self.end_of_text();
        }
        ids.resize(context_length, 0);
        (ids, truncated)
    }
}

/// CLIP's `whitespace_clean(basic_clean(text))`, as far as the module docs
/// say; lower-casing is left to the BPE step (it lower-cases itself).
pub fn clean(text: &str) -> String {
    let fixed = fix_text(text);
    let unescaped = html_unescape(&html_unescape(&fixed));
    let mut out = String::with_capacity(unescaped.len());
    for word in unescaped
        .split(char::is_whitespace)
        .filter(|w| !w.is_empty())
    {
        if !out.is_empty() {
            out.push(' ');
        }
        out.push_str(word);
    }
    out
}

/// The subset of `ftfy.fix_text` (default settings) that matters for
/// prompts.
fn fix_text(text: &str) -> String {
    let mut s = String::with_capacity(text.len());
    for c in text.chars() {
        match c {
            // uncurl_quotes
            '\u{02bc}' | '\u{2018}'..='\u{201b}' => s.push('\''),
            '\u{201c}'..='\u{201f}' => s.push('"'),
            // fix_latin_ligatures and fix_character_width use NFKC on these
            '\u{0132}'
            | '\u{0133}'
            | '\u{0149}'
            | '\u{01c4}'..='\u{01cc}'
            | '\u{01f1}'..='\u{01f3}'
            | '\u{fb00}'..='\u{fb06}'
            | '\u{3000}'
            | '\u{ff01}'..='\u{ffef}' => s.extend(std::iter::once(c).nfkc()),
            // remove_control_chars
            '\u{0}'..='\u{8}'
            | '\u{b}'
            | '\u{e}'..='\u{1f}'
            | '\u{7f}'
            | '\u{206a}'..='\u{206f}'
            | '\u{feff}'
            | '\u{fff9}'..='\u{fffc}' => {}
            _ => s.push(c),
        }
    }
    s.nfc().collect()
}

/// Python's `html.unescape` for numeric character references and the
/// named references prompts plausibly contain.
fn html_unescape(s: &str) -> String {
    if !s.contains('&') {
        return s.to_string();
    }
    let mut out = String::with_capacity(s.len());
    let mut rest = s;
    while let Some(pos) = rest.find('&') {
        out.push_str(&rest[..pos]);
        rest = &rest[pos..];
        match parse_reference(rest) {
            Some((c, len)) => {
                out.push_str(&c);
                rest = &rest[len..];
            }
            None => {
                out.push('&');
                rest = &rest[1..];
            }
        }
    }
    out.push_str(rest);
    out
}

/// Parses one reference at the start of `s` (which starts with `&`):
/// returns the replacement and the bytes consumed.
fn parse_reference(s: &str) -> Option<(String, usize)> {
    let body = &s[1..];
    if let Some(num) = body.strip_prefix('#') {
        let (digits, radix, skip) = match num.strip_prefix(['x', 'X']) {
            Some(hex) => (hex, 16, 2),
            None => (num, 10, 1),
        };
        let n = digits.chars().take_while(|c| c.is_digit(radix)).count();
        if n == 0 {
            return None;
        }
        let code = u32::from_str_radix(&digits[..n], radix).ok()?;
        let semi = usize::from(digits[n..].starts_with(';'));
        // Python maps invalid code points to U+FFFD and 0x80-0x9F through
        // cp1252; the replacement character covers what prompts will see.
        let c = char::from_u32(code)
            .filter(|&c| c != '\0')
            .unwrap_or('\u{fffd}');
        return Some((c.to_string(), 1 + skip + n + semi));
    }
    // Named references valid with or without ';' in HTML5, then ';'-only.
    const NAMED: [(&str, &str, bool); 8] = [
        ("amp", "&", false),
        ("lt", "<", false),
        ("gt", ">", false),
        ("quot", "\"", false),
        ("nbsp", "\u{a0}", false),
        ("copy", "\u{a9}", false),
        ("reg", "\u{ae}", false),
        ("apos", "'", true),
    ];
    for (name, rep, needs_semi) in NAMED {
        if let Some(after) = body.strip_prefix(name) {
            if after.starts_with(';') {
                return Some((rep.to_string(), 1 + name.len() + 1));
            }
            if !needs_semi {
                return Some((rep.to_string(), 1 + name.len()));
            }
        }
    }
    None
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn crate_example_and_markers() {
        let t = ClipTokenizer::new();
        assert_eq!(t.encode("Hi there"), vec![1883, 997]);
        assert_eq!((t.start_of_text(), t.end_of_text()), (49406, 49407));
        let (ids, cut) = t.tokenize("Hi there", 6);
        assert_eq!(ids, vec![49406, 1883, 997, 49407, 0, 0]);
        assert!(!cut);
    }

    #[test]
    fn long_text_is_cut_and_ends_with_the_end_marker() {
        let t = ClipTokenizer::new();
        let long = "word ".repeat(100);
        let (ids, cut) = t.tokenize(&long, CONTEXT_LENGTH);
        assert!(cut);
        assert_eq!(ids.len(), CONTEXT_LENGTH);
        assert_eq!(ids[0], 49406);
        assert_eq!(ids[CONTEXT_LENGTH - 1], 49407);
    }

    #[test]
    fn cleaning_matches_clip_on_quotes_widths_entities_and_spaces() {
        assert_eq!(
            clean("  It\u{2019}s\t\n a  \u{fb01}ne day "),
            "It's a fine day"
        );
        assert_eq!(clean("\u{ff21}\u{ff22}C"), "ABC");
        assert_eq!(clean("&amp;amp; &#x41;&#66; &lt;x&gt"), "& AB <x>");
        assert_eq!(clean("cafe\u{301}"), "caf\u{e9}");
        assert_eq!(clean("a&b &zzz;"), "a&b &zzz;");
    }
}
