//! Peer tools given on the command line as `NAME=COMMAND` templates.
//!
//! The command is split into words like a shell would for plain words and quotes (no
//! variables, globs or pipes: it is run directly, so the measured process is the tool
//! itself), and the placeholders `{in}` and `{out}` are replaced in each word by the input
//! and output paths of a run.

use std::path::Path;

/// Why a template was refused.
#[derive(Clone, Debug, PartialEq, Eq, thiserror::Error)]
pub enum TemplateError {
    /// No `=` between the name and the command.
    #[error("expected NAME=COMMAND, got `{0}`")]
    MissingName(String),
    /// The name is empty or holds characters unfit for a file name.
    #[error("peer name `{0}` must be non-empty and use only letters, digits, `-` and `_`")]
    BadName(String),
    /// A quote is not closed.
    #[error("unbalanced quote in `{0}`")]
    UnbalancedQuote(String),
    /// The command has no `{{in}}` or no `{{out}}`.
    #[error("the command of `{0}` must contain both {{in}} and {{out}}")]
    MissingPlaceholder(String),
}

/// A named command with `{in}` / `{out}` placeholders.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct CommandTemplate {
    /// Name shown in the tables and used in output file names.
    pub name: String,
    /// The words of the command, placeholders unexpanded.
    pub words: Vec<String>,
}

impl CommandTemplate {
    /// Parses `NAME=COMMAND`.
    pub fn parse(spec: &str) -> Result<CommandTemplate, TemplateError> {
        let (name, command) = spec
            .split_once('=')
            .ok_or_else(|| TemplateError::MissingName(spec.to_string()))?;
        let name = name.trim();
        if name.is_empty()
            || !name
                .chars()
                .all(|c| c.is_ascii_alphanumeric() || c == '-' || c == '_')
        {
            return Err(TemplateError::BadName(name.to_string()));
        }
        let words = split_words(command)
            .ok_or_else(|| TemplateError::UnbalancedQuote(command.to_string()))?;
        let has = |p: &str| words.iter().any(|w| w.contains(p));
        if !has("{in}") || !has("{out}") {
            return Err(TemplateError::MissingPlaceholder(name.to_string()));
        }
        Ok(CommandTemplate {
            name: name.to_string(),
            words,
        })
    }

    /// The command for one run.
    pub fn expand(&self, input: &Path, output: &Path) -> Vec<String> {
        let (i, o) = (input.display().to_string(), output.display().to_string());
        self.words
            .iter()
            .map(|w| w.replace("{in}", &i).replace("{out}", &o))
            .collect()
    }
}

/// Splits on unquoted whitespace; single quotes keep everything, double quotes keep
/// everything but `\"` and `\\`, a backslash outside quotes escapes the next character.
/// `None` for an unbalanced quote.
pub fn split_words(s: &str) -> Option<Vec<String>> {
    let mut words = Vec::new();
    let mut word = String::new();
    let mut in_word = false;
    let mut chars = s.chars();
    while let Some(c) = chars.next() {
        match c {
            c if c.is_whitespace() => {
                if in_word {
                    words.push(std::mem::take(&mut word));
                    in_word = false;
                }
            }
            '\'' => {
                in_word = true;
                loop {
                    match chars.next()? {
                        '\'' => break,
                        c => word.push(c),
                    }
                }
            }
            '"' => {
                in_word = true;
                loop {
                    match chars.next()? {
                        '"' => break,
                        '\\' => match chars.next()? {
                            c @ ('"' | '\\') => word.push(c),
                            c => {
                                word.push('\\');
                                word.push(c);
                            }
                        },
                        c => word.push(c),
                    }
                }
            }
            '\\' => {
                in_word = true;
                word.push(chars.next()?);
            }
            c => {
                in_word = true;
                word.push(c);
            }
        }
    }
    if in_word {
        words.push(word);
    }
    Some(words)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn templates_parse_and_expand() {
        let t =
            CommandTemplate::parse("poisson=python3 'peers/my script.py' {in} {out} --depth 10")
                .unwrap();
        assert_eq!(t.name, "poisson");
        assert_eq!(
            t.expand(Path::new("/a/b.ply"), Path::new("/c/d.ply")),
            vec![
                "python3",
                "peers/my script.py",
                "/a/b.ply",
                "/c/d.ply",
                "--depth",
                "10"
            ]
        );
        let t = CommandTemplate::parse("x=tool --in={in} -o \"{out}\"").unwrap();
        assert_eq!(
            t.expand(Path::new("i"), Path::new("o")),
            vec!["tool", "--in=i", "-o", "o"]
        );
    }

    #[test]
    fn bad_templates_are_refused() {
        assert!(matches!(
            CommandTemplate::parse("no name here"),
            Err(TemplateError::MissingName(_))
        ));
        assert!(matches!(
            CommandTemplate::parse("a/b=tool {in} {out}"),
            Err(TemplateError::BadName(_))
        ));
        assert!(matches!(
            CommandTemplate::parse("p=tool '{in} {out}"),
            Err(TemplateError::UnbalancedQuote(_))
        ));
        assert!(matches!(
            CommandTemplate::parse("p=tool {in}"),
            Err(TemplateError::MissingPlaceholder(_))
        ));
    }

    #[test]
    fn words_split_like_a_shell() {
        assert_eq!(
            split_words(r#"  a "b c" 'd "e"' f\ g "h\"i" "#).unwrap(),
            vec!["a", "b c", "d \"e\"", "f g", "h\"i"]
        );
        assert_eq!(split_words("''").unwrap(), vec![""]);
        assert!(split_words("\"open").is_none());
    }
}
