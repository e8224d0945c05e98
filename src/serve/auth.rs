//! Bearer tokens: `authorization: Bearer <token>` on every call but the
//! health checks. Tokens come from a file or the environment only.

use std::path::Path;

/// Why a call was refused; the message names what to fix without saying
/// anything about the server's maps or sessions.
#[derive(Debug, Clone, PartialEq, Eq, thiserror::Error)]
pub enum AuthError {
    #[error("missing credentials: send `authorization: Bearer <token>`")]
    Missing,
    #[error("the token is in the wrong place ({0}): send it as `authorization: Bearer <token>`")]
    WrongPlace(String),
    #[error("malformed authorization: expected `Bearer <token>`")]
    Malformed,
    #[error("invalid token")]
    Invalid,
}

/// The server's token.
#[derive(Clone)]
pub struct Token(String);

impl std::fmt::Debug for Token {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str("Token(..)")
    }
}

impl Token {
    /// A token of at least 16 characters of visible ASCII.
    pub fn new(s: &str) -> Result<Token, String> {
        let s = s.trim();
        if s.len() < 16 {
            return Err(format!(
                "the token has {} characters; use at least 16",
                s.len()
            ));
        }
        if !s.bytes().all(|b| b.is_ascii_graphic()) {
            return Err("the token must be visible ASCII without spaces".into());
        }
        Ok(Token(s.to_string()))
    }

    /// The first line of `path`.
    pub fn from_file(path: &Path) -> Result<Token, String> {
        let text = crate::io::bounded_read::read_text(path)
            .map_err(|e| format!("token file {}: {e}", path.display()))?;
        Token::new(text.lines().next().unwrap_or(""))
            .map_err(|e| format!("token file {}: {e}", path.display()))
    }

    /// Checks the value of an `authorization` header or metadata entry
    /// (`None` if absent); `elsewhere` names a place where a token was
    /// found instead (another header, the query string).
    pub fn check(&self, value: Option<&[u8]>, elsewhere: Option<&str>) -> Result<(), AuthError> {
        let Some(v) = value else {
            return Err(match elsewhere {
                Some(w) => AuthError::WrongPlace(w.to_string()),
                None => AuthError::Missing,
            });
        };
        let v = std::str::from_utf8(v).map_err(|_| AuthError::Malformed)?;
        let (scheme, tok) = v.trim().split_once(' ').ok_or(AuthError::Malformed)?;
        if !scheme.eq_ignore_ascii_case("bearer") {
            return Err(AuthError::Malformed);
        }
        if constant_time_eq(tok.trim().as_bytes(), self.0.as_bytes()) {
            Ok(())
        } else {
            Err(AuthError::Invalid)
        }
    }
}

/// Compares without stopping at the first difference.
fn constant_time_eq(a: &[u8], b: &[u8]) -> bool {
    if a.len() != b.len() {
        return false;
    }
    a.iter().zip(b).fold(0u8, |acc, (x, y)| acc | (x ^ y)) == 0
}

/// Header or metadata names where clients misplace tokens.
pub const MISPLACED: [&str; 4] = ["token", "x-api-key", "api-key", "x-auth-token"];

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn bearer_tokens_are_checked_exactly() {
        let t = Token::new("0123456789abcdef").unwrap();
        assert_eq!(t.check(Some(b"Bearer 0123456789abcdef"), None), Ok(()));
        assert_eq!(t.check(Some(b"bearer 0123456789abcdef"), None), Ok(()));
        assert_eq!(
            t.check(Some(b"Bearer 0123456789abcdeg"), None),
            Err(AuthError::Invalid)
        );
        assert_eq!(
            t.check(Some(b"Bearer 0123456789abcde"), None),
            Err(AuthError::Invalid)
        );
        assert_eq!(
            t.check(Some(b"0123456789abcdef"), None),
            Err(AuthError::Malformed)
        );
        assert_eq!(
            t.check(Some(b"Basic 0123456789abcdef"), None),
            Err(AuthError::Malformed)
        );
        assert_eq!(t.check(None, None), Err(AuthError::Missing));
        assert!(matches!(
            t.check(None, Some("x-api-key")),
            Err(AuthError::WrongPlace(_))
        ));
        assert!(Token::new("short").is_err());
        assert!(Token::new("0123456789 abcdef").is_err());
    }
}
