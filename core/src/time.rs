//! Times as people and tools read them: RFC 3339 in UTC.

use jiff::Timestamp;

/// Nanoseconds since 1970 (UTC) as RFC 3339 with nanoseconds, e.g.
/// `2023-11-14T22:13:20.123456789Z`.
pub fn rfc3339(ns: i64) -> String {
    let t = Timestamp::from_nanosecond(i128::from(ns)).unwrap_or(Timestamp::UNIX_EPOCH);
    format!("{t:.9}")
}

/// The current time in RFC 3339, UTC.
pub fn now_rfc3339() -> String {
    format!("{:.9}", Timestamp::now())
}

#[cfg(test)]
mod tests {
    use super::rfc3339;

    #[test]
    fn formats_utc_times() {
        assert_eq!(rfc3339(0), "1970-01-01T00:00:00.000000000Z");
        assert_eq!(
            rfc3339(1_700_000_000_123_456_789),
            "2023-11-14T22:13:20.123456789Z"
        );
        assert_eq!(
            rfc3339(951_782_400_000_000_000),
            "2000-02-29T00:00:00.000000000Z"
        );
    }
}
