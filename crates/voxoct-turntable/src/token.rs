//! The token from the environment: one variable name for the server and the
//! scanner alike.

use std::ffi::OsString;

use crate::TurntableError;

/// The environment variable that holds the shared-secret token, read by
/// `turntable_server` (when `--token` is not given) and by the scanner.
pub const TOKEN_ENV: &str = "VOXOCT_TURNTABLE_TOKEN";

/// The name older versions of the server read. It is refused rather than
/// ignored, so that a token is never silently dropped (which would leave
/// the table open, or lock the scanner out).
const OLD_TOKEN_ENV: &str = "VOXOCT_TT_TOKEN";

/// The token in [`TOKEN_ENV`]: `None` when unset or empty.
///
/// # Errors
/// [`TurntableError::Config`] when the old variable `VOXOCT_TT_TOKEN` is set
/// (how to fix: rename it to [`TOKEN_ENV`]), or when [`TOKEN_ENV`] is not
/// valid UTF-8. The token's own rules are checked where it is used
/// ([`serve`](crate::serve), [`RemoteTurntable::connect`](crate::RemoteTurntable::connect)).
pub fn token_from_env() -> Result<Option<String>, TurntableError> {
    token_from(|name| std::env::var_os(name))
}

fn token_from(var: impl Fn(&str) -> Option<OsString>) -> Result<Option<String>, TurntableError> {
    if var(OLD_TOKEN_ENV).is_some() {
        return Err(TurntableError::Config(format!(
            "{OLD_TOKEN_ENV} is no longer read; the token variable is {TOKEN_ENV} (the same as \
             the scanner's). How to fix: rename the variable"
        )));
    }
    match var(TOKEN_ENV) {
        None => Ok(None),
        Some(v) if v.is_empty() => Ok(None),
        Some(v) => v
            .into_string()
            .map(Some)
            .map_err(|_| TurntableError::Config(format!("{TOKEN_ENV} is not valid UTF-8"))),
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn env(vars: &[(&str, &str)]) -> impl Fn(&str) -> Option<OsString> {
        let vars: Vec<(String, OsString)> = vars
            .iter()
            .map(|(k, v)| ((*k).to_string(), OsString::from(v)))
            .collect();
        move |name| vars.iter().find(|(k, _)| k == name).map(|(_, v)| v.clone())
    }

    #[test]
    fn one_name_is_read_and_the_old_one_refused() {
        assert_eq!(token_from(env(&[])).unwrap(), None);
        assert_eq!(token_from(env(&[(TOKEN_ENV, "")])).unwrap(), None);
        assert_eq!(
            token_from(env(&[(TOKEN_ENV, "s3cret")])).unwrap(),
            Some("s3cret".to_string())
        );
        for vars in [
            &[(OLD_TOKEN_ENV, "s3cret")][..],
            &[(OLD_TOKEN_ENV, "old"), (TOKEN_ENV, "new")][..],
        ] {
            let err = token_from(env(vars)).unwrap_err();
            let msg = err.to_string();
            assert!(matches!(err, TurntableError::Config(_)), "{msg}");
            assert!(
                msg.contains(OLD_TOKEN_ENV) && msg.contains(TOKEN_ENV),
                "{msg}"
            );
            assert!(!msg.contains("s3cret"), "the token is never echoed: {msg}");
        }
    }

    #[cfg(unix)]
    #[test]
    fn a_token_that_is_not_utf8_is_refused() {
        use std::os::unix::ffi::OsStringExt;
        let bytes = OsString::from_vec(vec![0x73, 0xff]);
        let err = token_from(move |name| (name == TOKEN_ENV).then(|| bytes.clone())).unwrap_err();
        assert!(err.to_string().contains(TOKEN_ENV), "{err}");
    }
}
