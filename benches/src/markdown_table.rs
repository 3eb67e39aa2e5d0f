//! Plain markdown tables and the number formats the benchmark tables share.

/// A markdown table built row by row.
#[derive(Clone, Debug, Default, PartialEq, Eq)]
pub struct MarkdownTable {
    header: Vec<String>,
    rows: Vec<Vec<String>>,
}

impl MarkdownTable {
    /// A table with these column titles.
    pub fn new<S: Into<String>>(header: impl IntoIterator<Item = S>) -> MarkdownTable {
        MarkdownTable {
            header: header.into_iter().map(Into::into).collect(),
            rows: Vec::new(),
        }
    }

    /// Appends a row; missing cells are left empty and extra cells are dropped, so the table
    /// stays rectangular.
    pub fn push(&mut self, mut row: Vec<String>) {
        row.resize(self.header.len(), String::new());
        self.rows.push(row);
    }

    /// Number of rows.
    pub fn len(&self) -> usize {
        self.rows.len()
    }

    /// True when there is no row.
    pub fn is_empty(&self) -> bool {
        self.rows.is_empty()
    }

    /// The table as markdown, columns padded to line up in plain text too. A `|` inside a
    /// cell is escaped.
    pub fn render(&self) -> String {
        let cell = |s: &str| s.replace('|', "\\|");
        let widths: Vec<usize> = (0..self.header.len())
            .map(|c| {
                self.rows
                    .iter()
                    .map(|r| cell(&r[c]).chars().count())
                    .chain([self.header[c].chars().count(), 3])
                    .max()
                    .unwrap_or(3)
            })
            .collect();
        let line = |cells: Vec<String>| {
            let padded: Vec<String> = cells
                .iter()
                .zip(&widths)
                .map(|(c, &w)| format!("{c:<w$}"))
                .collect();
            format!("| {} |\n", padded.join(" | "))
        };
        let mut out = line(self.header.iter().map(|h| cell(h)).collect());
        out += &line(widths.iter().map(|&w| "-".repeat(w)).collect());
        for r in &self.rows {
            out += &line(r.iter().map(|c| cell(c)).collect());
        }
        out
    }
}

/// `x` with `digits` decimals, or `–` when absent.
pub fn fixed(x: Option<f64>, digits: usize) -> String {
    x.map_or_else(|| "–".to_string(), |x| format!("{x:.digits$}"))
}

/// Parses a point count such as `100k`, `362K`, `1M`, `1.5m` or `2000`.
pub fn parse_count(s: &str) -> Option<usize> {
    let s = s.trim();
    let (num, mult) = match s.chars().last()? {
        'k' | 'K' => (&s[..s.len() - 1], 1e3),
        'm' | 'M' => (&s[..s.len() - 1], 1e6),
        _ => (s, 1.0),
    };
    let x: f64 = num.parse().ok()?;
    let n = (x * mult).round();
    (x.is_finite() && n >= 1.0 && n <= usize::MAX as f64).then_some(n as usize)
}

/// A point count as written in tables: `100K`, `362K`, `1M`, `1.5M`, or the plain number.
pub fn format_count(n: usize) -> String {
    if n >= 1_000_000 && n.is_multiple_of(100_000) {
        format!("{}M", n as f64 / 1e6)
    } else if n >= 1000 && n.is_multiple_of(1000) {
        format!("{}K", n / 1000)
    } else {
        n.to_string()
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn tables_render_aligned_and_escaped() {
        let mut t = MarkdownTable::new(["a", "long title"]);
        t.push(vec!["x|y".into(), "1".into(), "dropped".into()]);
        t.push(vec!["z".into()]);
        assert_eq!(
            t.render(),
            "| a    | long title |\n| ---- | ---------- |\n| x\\|y | 1          |\n| z    |            |\n"
        );
    }

    #[test]
    fn counts_parse_and_format() {
        assert_eq!(parse_count("100k"), Some(100_000));
        assert_eq!(parse_count("362K"), Some(362_000));
        assert_eq!(parse_count("1.5M"), Some(1_500_000));
        assert_eq!(parse_count("2000"), Some(2000));
        assert_eq!(parse_count("0"), None);
        assert_eq!(parse_count("-3k"), None);
        assert_eq!(parse_count("k"), None);
        assert_eq!(parse_count(""), None);
        for n in [100_000, 362_000, 1_000_000, 3_000_000, 1234] {
            assert_eq!(parse_count(&format_count(n)), Some(n));
        }
        assert_eq!(format_count(1_000_000), "1M");
        assert_eq!(fixed(None, 2), "–");
        assert_eq!(fixed(Some(1.23456), 3), "1.235");
    }
}
