//! The command lines a reader copies from README.md and the book
//! (`docs/src/**/*.md`), found and split the way a shell would, for the
//! binaries' tests to parse with their own clap definitions.
//!
//! Shared by `sim-client` (`sim-client/cli/src/doc_commands.rs`) and
//! `sim-server` (`sim-server/src/doc_commands.rs`, which includes this file
//! by path), so both read the documentation the same way. Test code only.
//!
//! What counts as a command line:
//! - in a ```` ```sh ```` (`bash`, `shell`, `console`) block, every line (a
//!   `\` continuation joined, a heredoc's body skipped, a comment cut off),
//!   split at `&&`, `||`, `;`, `|` and `&` into simple commands;
//! - in a ```` ```text ```` block, a line after a `$ ` prompt;
//! - in prose, an inline code span that starts with the program's name:
//!   a fragment (`sim-client bridge zenoh`) may leave out required
//!   arguments, but every flag and value it names must parse.
//!
//! A simple command runs the program when its first word (after `VAR=value`
//! assignments and `do`/`then`/`else`/`time`/`exec`) is the program's name
//! or a path ending in it (`./target/release/sim-client`), or is `cargo run`
//! of its package or binary (the arguments after `--`). Redirections are
//! dropped; `$VAR` and `${VAR}` become a sample value.

use std::fmt;
use std::path::{Path, PathBuf};

use clap::error::ErrorKind;

/// One command line found in the documentation.
#[derive(Debug, Clone, PartialEq, Eq)]
pub(crate) struct DocCommand {
    /// Where it is: `README.md:42`.
    pub(crate) place: String,
    /// The program's name and its arguments, as the shell passes them.
    pub(crate) argv: Vec<String>,
    /// From an inline code span in prose: a fragment that may leave out
    /// required arguments.
    pub(crate) fragment: bool,
}

impl fmt::Display for DocCommand {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(f, "{}: `{}`", self.place, self.argv.join(" "))
    }
}

/// The repository's root: the first ancestor of this crate's manifest
/// directory that holds the book.
pub(crate) fn repository_root() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR"))
        .ancestors()
        .find(|dir| dir.join("docs/src/SUMMARY.md").is_file())
        .expect("the repository root, with docs/src/SUMMARY.md, above this crate")
        .to_path_buf()
}

/// README.md and every Markdown file under docs/src/, sorted, as paths
/// relative to `root`.
pub(crate) fn documents(root: &Path) -> Vec<PathBuf> {
    fn walk(dir: &Path, out: &mut Vec<PathBuf>) {
        let entries = std::fs::read_dir(dir).unwrap_or_else(|e| panic!("{}: {e}", dir.display()));
        for entry in entries {
            let path = entry.expect("a directory entry").path();
            if path.is_dir() {
                walk(&path, out);
            } else if path.extension().is_some_and(|e| e == "md") {
                out.push(path);
            }
        }
    }
    let mut found = Vec::new();
    walk(&root.join("docs/src"), &mut found);
    found.sort();
    let mut all = vec![PathBuf::from("README.md")];
    all.extend(
        found
            .into_iter()
            .map(|p| p.strip_prefix(root).expect("under the root").to_path_buf()),
    );
    all
}

/// Every command line running `program` (`sim-client` or `sim-server`) in
/// README.md and the book.
pub(crate) fn in_the_docs(program: &str) -> Vec<DocCommand> {
    let root = repository_root();
    documents(&root)
        .iter()
        .flat_map(|doc| {
            let text = std::fs::read_to_string(root.join(doc))
                .unwrap_or_else(|e| panic!("{}: {e}", doc.display()));
            commands_in(&doc.display().to_string(), &text, program)
        })
        .collect()
}

/// Parses every command with `parse` (the binary's `Args::try_parse_from`)
/// and returns one line per failure: where, the command, clap's error.
/// `--help` and `--version` are successes; a fragment may miss required
/// arguments and a subcommand.
pub(crate) fn failures(
    commands: &[DocCommand],
    parse: impl Fn(&[String]) -> Result<(), clap::Error>,
) -> Vec<String> {
    commands
        .iter()
        .filter_map(|command| {
            let error = parse(&command.argv).err()?;
            let fine = match error.kind() {
                ErrorKind::DisplayHelp | ErrorKind::DisplayVersion => true,
                ErrorKind::MissingRequiredArgument
                | ErrorKind::MissingSubcommand
                | ErrorKind::DisplayHelpOnMissingArgumentOrSubcommand => command.fragment,
                _ => false,
            };
            (!fine).then(|| format!("{command}\n    {}", error.render().to_string().trim()))
        })
        .collect()
}

/// The command lines running `program` in one Markdown document.
pub(crate) fn commands_in(doc: &str, text: &str, program: &str) -> Vec<DocCommand> {
    let mut found = Vec::new();
    let mut fence: Option<(String, String)> = None; // (the fence, the language)
    let mut heredoc: Option<String> = None;
    let mut pending: Option<(usize, String)> = None; // a line continued with `\`
    for (index, line) in text.lines().enumerate() {
        let number = index + 1;
        let trimmed = line.trim_start();
        if let Some((marker, _)) = &fence {
            if heredoc.is_none() && trimmed.starts_with(marker.as_str()) {
                fence = None;
                pending = None;
                continue;
            }
        } else {
            fence = fence_opening(trimmed);
            if fence.is_none() {
                found.extend(inline_commands(doc, number, line, program));
            }
            continue;
        }
        let language = fence.as_ref().map(|(_, l)| l.as_str()).unwrap_or("");
        let Some(shell) = shell_line(language, line) else {
            continue;
        };
        if let Some(end) = &heredoc {
            if shell.trim() == end {
                heredoc = None;
            }
            continue;
        }
        let (start, mut whole) = match pending.take() {
            Some((start, before)) => (start, before + " " + shell.trim()),
            None => (number, shell),
        };
        if let Some(continued) = whole.strip_suffix('\\') {
            pending = Some((start, continued.to_owned()));
            continue;
        }
        heredoc = heredoc_end(&whole);
        whole = without_comment(&whole);
        found.extend(
            simple_commands(&whole, program)
                .into_iter()
                .map(|argv| DocCommand {
                    place: format!("{doc}:{start}"),
                    argv,
                    fragment: false,
                }),
        );
    }
    found
}

/// The fence (its backticks) and the language a line opening a fenced
/// code block names; `None` for any other line.
fn fence_opening(trimmed: &str) -> Option<(String, String)> {
    let rest = trimmed.strip_prefix("```")?;
    let ticks = 3 + rest.chars().take_while(|c| *c == '`').count();
    let info = &trimmed[ticks..];
    let language = info
        .split(|c: char| c == ',' || c.is_whitespace())
        .next()
        .unwrap_or("");
    Some(("`".repeat(ticks), language.to_owned()))
}

/// The command fragments in the inline code spans of line `number` of prose.
fn inline_commands(doc: &str, number: usize, line: &str, program: &str) -> Vec<DocCommand> {
    let mut found = Vec::new();
    for span in inline_code(line) {
        found.extend(
            simple_commands(span, program)
                .into_iter()
                // `sim-client …`: what follows the ellipsis is left out.
                .map(|argv| {
                    argv.into_iter()
                        .take_while(|w| w != "…" && w != "...")
                        .collect()
                })
                .map(|argv| DocCommand {
                    place: format!("{doc}:{number}"),
                    argv,
                    fragment: true,
                }),
        );
    }
    found
}

/// The shell a line of a code block in `language` runs, if any: every line
/// of a shell block, the `$ ` lines of a text block.
fn shell_line(language: &str, line: &str) -> Option<String> {
    match language {
        "sh" | "bash" | "shell" | "console" | "zsh" => Some(line.to_owned()),
        "text" => line
            .trim_start()
            .strip_prefix("$ ")
            .map(|command| command.to_owned()),
        _ => None,
    }
}

/// The inline code spans of one line of prose.
fn inline_code(line: &str) -> Vec<&str> {
    let mut spans = Vec::new();
    let mut rest = line;
    while let Some(open) = rest.find('`') {
        let ticks = rest[open..].chars().take_while(|c| *c == '`').count();
        let marker = &rest[open..open + ticks];
        let body = &rest[open + ticks..];
        match body.find(marker) {
            Some(close) => {
                spans.push(body[..close].trim());
                rest = &body[close + ticks..];
            }
            None => break,
        }
    }
    spans
}

/// The word a heredoc on this line ends with (`<<'PY'`, `<<EOF`, `<<-X`).
fn heredoc_end(line: &str) -> Option<String> {
    let at = line.find("<<")?;
    let word = line[at + 2..].trim_start_matches('-').trim_start();
    let word: String = word
        .chars()
        .take_while(|c| !c.is_whitespace() && *c != ';' && *c != '&' && *c != '|')
        .filter(|c| *c != '\'' && *c != '"')
        .collect();
    (!word.is_empty()).then_some(word)
}

/// The line up to a comment: a `#` that starts a word outside quotes.
fn without_comment(line: &str) -> String {
    let mut quote = None;
    let mut previous = ' ';
    for (at, c) in line.char_indices() {
        match (quote, c) {
            (None, '\'' | '"') => quote = Some(c),
            (Some(q), c) if c == q => quote = None,
            (None, '#') if previous.is_whitespace() => return line[..at].to_owned(),
            _ => {}
        }
        previous = c;
    }
    line.to_owned()
}

/// Splits a line into simple commands and returns the argument vectors of
/// those that run `program`.
fn simple_commands(line: &str, program: &str) -> Vec<Vec<String>> {
    let mut commands = Vec::new();
    let mut words: Vec<String> = Vec::new();
    let mut word = String::new();
    let mut in_word = false;
    let mut chars = line.chars().peekable();
    let mut quote: Option<char> = None;
    let end_word = |words: &mut Vec<String>, word: &mut String, in_word: &mut bool| {
        if *in_word {
            words.push(std::mem::take(word));
            *in_word = false;
        }
    };
    while let Some(c) = chars.next() {
        match quote {
            Some(q) if c == q => quote = None,
            Some('"') if c == '\\' => word.extend(chars.next()),
            Some(_) => word.push(c),
            None => match c {
                '\'' | '"' => {
                    quote = Some(c);
                    in_word = true;
                }
                '\\' => {
                    word.extend(chars.next());
                    in_word = true;
                }
                ';' | '|' | '&' => {
                    // `2>&1` and `>&2` are redirections, not separators.
                    if c == '&' && word.ends_with('>') {
                        word.push(c);
                        continue;
                    }
                    end_word(&mut words, &mut word, &mut in_word);
                    if chars.peek() == Some(&c) {
                        chars.next();
                    }
                    commands.push(std::mem::take(&mut words));
                }
                c if c.is_whitespace() => end_word(&mut words, &mut word, &mut in_word),
                c => {
                    word.push(c);
                    in_word = true;
                }
            },
        }
    }
    end_word(&mut words, &mut word, &mut in_word);
    commands.push(words);
    commands
        .into_iter()
        .filter_map(|words| argv_of(words, program))
        .collect()
}

/// The argument vector of a simple command if it runs `program`.
fn argv_of(words: Vec<String>, program: &str) -> Option<Vec<String>> {
    let mut words = without_redirections(words).into_iter().peekable();
    while let Some(first) = words.peek() {
        let assignment = first.split_once('=').is_some_and(|(name, _)| {
            !name.is_empty() && name.chars().all(|c| c.is_ascii_alphanumeric() || c == '_')
        });
        let keyword = matches!(
            first.as_str(),
            "do" | "then" | "else" | "time" | "exec" | "nohup"
        );
        if !(assignment || keyword) {
            break;
        }
        words.next();
    }
    let first = words.next()?;
    let rest: Vec<String> = words.map(|w| with_samples(&w)).collect();
    let runs = |name: &str| name == program || name.ends_with(&format!("/{program}"));
    if runs(&first) {
        return Some(std::iter::once(program.to_owned()).chain(rest).collect());
    }
    if first == "cargo" && rest.first().is_some_and(|w| w == "run") {
        let split = rest.iter().position(|w| w == "--").unwrap_or(rest.len());
        let (cargo, args) = rest.split_at(split);
        let package = match program {
            "sim-client" => "sim-client-cli",
            _ => program,
        };
        let named = cargo.windows(2).any(|pair| {
            matches!(pair[0].as_str(), "-p" | "--package" | "--bin")
                && (pair[1] == package || pair[1] == program)
        }) || cargo
            .iter()
            .any(|w| *w == format!("--package={package}") || *w == format!("--bin={program}"));
        if named {
            let args = args.iter().skip(1).cloned();
            return Some(std::iter::once(program.to_owned()).chain(args).collect());
        }
    }
    None
}

/// The words without shell redirections (`> FILE`, `2>&1`, `<FILE`).
fn without_redirections(words: Vec<String>) -> Vec<String> {
    let mut kept = Vec::new();
    let mut words = words.into_iter();
    while let Some(word) = words.next() {
        let operator = word.trim_start_matches(|c: char| c.is_ascii_digit());
        if matches!(operator, ">" | ">>" | "<" | "<<" | "<<<" | ">|") {
            words.next(); // its target
        } else if !(operator.starts_with('>') || operator.starts_with('<')) {
            kept.push(word);
        }
    }
    kept
}

/// A word with its `$VAR`s and `${VAR}`s replaced by sample values: `$w`
/// (a world in the determinism recipe) by `run-a`, any other by `1`.
fn with_samples(word: &str) -> String {
    let mut out = String::new();
    let mut rest = word;
    while let Some(at) = rest.find('$') {
        out.push_str(&rest[..at]);
        let after = &rest[at + 1..];
        let (name, tail) = if let Some(braced) = after.strip_prefix('{') {
            match braced.find('}') {
                Some(close) => (&braced[..close], &braced[close + 1..]),
                None => (braced, ""),
            }
        } else {
            let len = after
                .find(|c: char| !(c.is_ascii_alphanumeric() || c == '_'))
                .unwrap_or(after.len());
            (&after[..len], &after[len..])
        };
        if name.is_empty() {
            out.push('$');
        } else {
            out.push_str(if name == "w" { "run-a" } else { "1" });
        }
        rest = tail;
    }
    out.push_str(rest);
    out
}

/// One failure per flag that a synopsis in a table of README.md or the book
/// names and `root` (the binary's `Args::command()`) does not have.
///
/// A synopsis is the first cell of a table row when it opens with a code
/// span that names a subcommand (`` `watch [--frames N] [--json]` ``), or,
/// under a heading that names the program (`` ### `sim-server` ``), a flag
/// (`` `--delta-seconds S` (or `--fixed-delta-seconds`) / `--fps N` ``).
/// Every `--flag` in the cell must be one of that subcommand's (or one of
/// its subcommands'), or a global one.
pub(crate) fn synopsis_failures(root: &clap::Command, program: &str) -> Vec<String> {
    let repository = repository_root();
    let mut failed = Vec::new();
    for doc in documents(&repository) {
        let text = std::fs::read_to_string(repository.join(&doc))
            .unwrap_or_else(|e| panic!("{}: {e}", doc.display()));
        failed.extend(synopses_in(
            &doc.display().to_string(),
            &text,
            root,
            program,
        ));
    }
    failed
}

/// The synopsis failures of one Markdown document.
pub(crate) fn synopses_in(
    doc: &str,
    text: &str,
    root: &clap::Command,
    program: &str,
) -> Vec<String> {
    let mut failed = Vec::new();
    let mut in_fence = false;
    let mut under_program = false;
    for (index, line) in text.lines().enumerate() {
        if line.trim_start().starts_with("```") {
            in_fence = !in_fence;
            continue;
        }
        if in_fence {
            continue;
        }
        if line.starts_with('#') {
            under_program = line.contains(&format!("`{program}`"));
            continue;
        }
        let Some(row) = line.strip_prefix('|') else {
            continue;
        };
        let cell = first_cell(row);
        if !cell.trim_start().starts_with('`') {
            continue;
        }
        let spans = inline_code(&cell);
        // The first span says what the row is about; a later one that names
        // a subcommand (`` `recorder time-factor F` / `recorder stop-replay` ``)
        // starts another.
        let Some(mut about) = synopsis_command(root, spans[0], program, under_program) else {
            continue;
        };
        for span in spans {
            if let Some(next) = synopsis_command(root, span, program, false) {
                about = next;
            }
            let (path, command) = &about;
            let known = flags_of(root, command);
            for flag in long_flags(span) {
                if !known.contains(&flag) {
                    failed.push(format!(
                        "{doc}:{}: {} names {flag}, which `{program}{path}` does not have",
                        index + 1,
                        cell.trim(),
                    ));
                }
            }
        }
    }
    failed
}

/// A table row's first cell, with `\|` (a `|` inside it) unescaped.
fn first_cell(row: &str) -> String {
    let mut cell = String::new();
    let mut chars = row.chars();
    while let Some(c) = chars.next() {
        match c {
            '\\' => cell.extend(chars.next()),
            '|' => break,
            c => cell.push(c),
        }
    }
    cell
}

/// The (sub)command a synopsis span is about, if it is one, with its path
/// (` recorder blocked`; empty for the program itself).
fn synopsis_command<'a>(
    root: &'a clap::Command,
    span: &str,
    program: &str,
    under_program: bool,
) -> Option<(String, &'a clap::Command)> {
    let mut words = span.split_whitespace().peekable();
    if words.peek() == Some(&program) {
        words.next();
    }
    let first = *words.peek()?;
    if first.starts_with("--") {
        return under_program.then(|| (String::new(), root));
    }
    let mut command = root.find_subcommand(first)?;
    let mut path = format!(" {}", command.get_name());
    words.next();
    for word in words {
        match command.find_subcommand(word) {
            Some(sub) => {
                command = sub;
                path = format!("{path} {}", sub.get_name());
            }
            None if word.starts_with('-') || word.starts_with('[') => break,
            None => {}
        }
    }
    Some((path, command))
}

/// Every long flag (and alias) of `command` and its subcommands, and the
/// global ones of `root`.
fn flags_of(root: &clap::Command, command: &clap::Command) -> Vec<String> {
    fn walk(command: &clap::Command, out: &mut Vec<String>) {
        for arg in command.get_arguments() {
            if let Some(long) = arg.get_long() {
                out.push(format!("--{long}"));
            }
            for alias in arg.get_all_aliases().unwrap_or_default() {
                out.push(format!("--{alias}"));
            }
        }
        for sub in command.get_subcommands() {
            walk(sub, out);
        }
    }
    let mut known = vec!["--help".to_owned(), "--version".to_owned()];
    walk(command, &mut known);
    known.extend(
        root.get_arguments()
            .filter(|arg| arg.is_global_set())
            .filter_map(|arg| arg.get_long())
            .map(|long| format!("--{long}")),
    );
    known
}

/// The `--flags` a span names.
fn long_flags(span: &str) -> Vec<String> {
    let mut flags = Vec::new();
    let mut rest = span;
    while let Some(at) = rest.find("--") {
        let name: String = rest[at + 2..]
            .chars()
            .take_while(|c| c.is_ascii_alphanumeric() || *c == '-')
            .collect();
        let preceded = rest[..at].chars().last();
        if !name.is_empty() && !preceded.is_some_and(|c| c.is_ascii_alphanumeric() || c == '-') {
            flags.push(format!("--{name}"));
        }
        rest = &rest[at + 2 + name.len()..];
    }
    flags
}
