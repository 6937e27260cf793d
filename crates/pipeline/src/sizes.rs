//! Sizes as people write them (`4G`, `50M`), read the same by every front end.

/// A size as people write it: `N` with an optional suffix (any case) `K`, `M`, `G`, `T` for
/// `unit`, `unit`², ... (1000 for pixels, 1024 for bytes), greater than 0; `what` names the unit
/// in the message. The command line's `--max-memory`/`--max-pixels` and Python's `max_memory`.
pub fn parse_scaled(text: &str, unit: u64, what: &str) -> Result<u64, String> {
    let text = text.trim();
    let (digits, power) = match text.char_indices().last() {
        Some((i, c)) if c.is_ascii_alphabetic() => {
            let power = match c.to_ascii_uppercase() {
                'K' => 1,
                'M' => 2,
                'G' => 3,
                'T' => 4,
                _ => return Err(format!("unknown suffix {c:?} (want K, M, G or T)")),
            };
            (&text[..i], power)
        }
        _ => (text, 0),
    };
    let n: u64 = digits.parse().map_err(|_| format!("not a whole number of {what}: {text:?}"))?;
    let value = unit.checked_pow(power).and_then(|scale| n.checked_mul(scale)).ok_or("too large")?;
    if value == 0 {
        return Err("must be greater than 0".into());
    }
    Ok(value)
}

#[cfg(test)]
mod tests {
    use super::parse_scaled;

    #[test]
    fn suffixes_scale_by_the_unit() {
        assert_eq!(parse_scaled("4G", 1024, "bytes"), Ok(4 << 30));
        assert_eq!(parse_scaled(" 50m", 1000, "pixels"), Ok(50_000_000));
        assert_eq!(parse_scaled("7", 1024, "bytes"), Ok(7));
        assert!(parse_scaled("4X", 1024, "bytes").unwrap_err().contains("unknown suffix"));
        assert!(parse_scaled("0", 1024, "bytes").is_err());
        assert!(parse_scaled("99999999T", 1024, "bytes").is_err());
    }
}
