//! Sizes in bytes as people write and read them: `2G`, `500M`, `1.5GiB`, `800000` in,
//! `1.2 GiB` out (powers of 1024, as `free -h` and `/usr/bin/time` count).

/// Parses a size: a non-negative number, then optionally a unit `K`, `M`, `G` or `T`
/// (powers of 1024, as `free -h` and `/usr/bin/time` count), with or without `B`/`iB`;
/// a bare number or `B` is bytes. Case does not matter.
pub fn parse_byte_size(text: &str) -> Result<u64, String> {
    let trimmed = text.trim();
    let split = trimmed
        .find(|c: char| !(c.is_ascii_digit() || c == '.'))
        .unwrap_or(trimmed.len());
    let (number, unit) = trimmed.split_at(split);
    let value: f64 = number
        .parse()
        .map_err(|_| format!("`{text}` is not a size (examples: 2G, 500M, 1.5GiB)"))?;
    let scale: f64 = match unit.trim().to_ascii_uppercase().as_str() {
        "" | "B" => 1.0,
        "K" | "KB" | "KIB" => 1024.0,
        "M" | "MB" | "MIB" => 1024.0 * 1024.0,
        "G" | "GB" | "GIB" => 1024.0 * 1024.0 * 1024.0,
        "T" | "TB" | "TIB" => 1024.0 * 1024.0 * 1024.0 * 1024.0,
        other => {
            return Err(format!(
                "unknown unit `{other}` in `{text}` (use K, M, G or T)"
            ));
        }
    };
    let bytes = value * scale;
    if !bytes.is_finite() || bytes >= u64::MAX as f64 {
        return Err(format!("`{text}` is too large"));
    }
    Ok(bytes.round() as u64)
}

/// A size for people: `1.2 GiB`, `456.7 MiB`, `12.0 KiB`, `800 B` (powers of 1024, one
/// decimal; TiB is the largest unit).
pub fn format_byte_size(bytes: u64) -> String {
    const UNITS: [&str; 4] = ["KiB", "MiB", "GiB", "TiB"];
    if bytes < 1024 {
        return format!("{bytes} B");
    }
    let mut value = bytes as f64;
    let mut unit = "B";
    for name in UNITS {
        if value < 1024.0 {
            break;
        }
        value /= 1024.0;
        unit = name;
    }
    format!("{value:.1} {unit}")
}

#[cfg(test)]
mod tests {
    use super::*;
    use proptest::prelude::*;

    #[test]
    fn units_are_powers_of_1024() {
        assert_eq!(parse_byte_size("800"), Ok(800));
        assert_eq!(parse_byte_size("2k"), Ok(2048));
        assert_eq!(parse_byte_size("500M"), Ok(500 << 20));
        assert_eq!(parse_byte_size("2G"), Ok(2 << 30));
        assert_eq!(parse_byte_size("1.5GiB"), Ok(3 << 29));
        assert_eq!(parse_byte_size(" 3 TB "), Ok(3 << 40));
    }

    #[test]
    fn nonsense_is_refused() {
        for text in ["", "G", "-1G", "2X", "1e3", "1.2.3M", "99999999999T"] {
            assert!(parse_byte_size(text).is_err(), "{text}");
        }
    }

    proptest! {
        #[test]
        fn formatted_sizes_parse_back_within_rounding(bytes in 0u64..(1u64 << 50)) {
            let text = format_byte_size(bytes).replace(' ', "");
            let back = parse_byte_size(&text).unwrap() as f64;
            // One decimal: within 0.05 of the unit, i.e. 5% of 1 unit at worst.
            prop_assert!((back - bytes as f64).abs() <= 0.05 * (bytes as f64).max(1.0) + 1.0);
        }
    }
}
