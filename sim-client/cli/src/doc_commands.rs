//! Every `sim-client …` command line in README.md and the book
//! (`docs/src/**/*.md`) parses with this binary's own clap definitions, so
//! a renamed or removed flag fails the suite until the documentation
//! follows (`lines.rs` says what counts as a command line).

mod lines;

use clap::{CommandFactory, Parser};

use super::Args;
use lines::{commands_in, failures, in_the_docs, synopses_in, synopsis_failures};

/// Parses one argument vector as `sim-client` does.
fn parse(argv: &[String]) -> Result<(), clap::Error> {
    Args::try_parse_from(argv).map(drop)
}

/// Whether this build has the subcommand `argv` runs: the adapters'
/// subcommands exist only with their cargo features (`cargo test
/// --no-default-features` checks the rest).
fn built_in(argv: &[String]) -> bool {
    let mut words = argv.iter().skip(1);
    let subcommand = loop {
        match words.next().map(String::as_str) {
            Some("--world" | "--timeout") => {
                words.next();
            }
            Some(flag) if flag.starts_with('-') => {}
            other => break other,
        }
    };
    let adapter = match subcommand {
        Some("carla-gateway") => Some(cfg!(feature = "carla")),
        Some("foxglove") => Some(cfg!(feature = "foxglove")),
        Some("bridge") => Some(cfg!(feature = "zenoh")),
        _ => None,
    };
    adapter.unwrap_or(true)
}

#[test]
fn every_sim_client_command_line_in_the_docs_parses() {
    let commands: Vec<_> = in_the_docs("sim-client")
        .into_iter()
        .filter(|c| built_in(&c.argv))
        .collect();
    let whole: Vec<_> = commands.iter().filter(|c| !c.fragment).collect();
    // The extraction finds what a reader copies: the demo, the recipe's
    // ticker, the bridge's two ends (a test that finds nothing proves nothing).
    assert!(
        whole.len() >= 30,
        "{} command lines: {whole:#?}",
        whole.len()
    );
    for expected in [
        "sim-client demo",
        "sim-client --world run-a tick --count 1000 --participants 2 --leave-sync",
        "sim-client --world W bridge zenoh --connect tcp/10.0.0.1:7447",
    ]
    .into_iter()
    .filter(|expected| cfg!(feature = "zenoh") || !expected.contains("zenoh"))
    {
        assert!(
            whole.iter().any(|c| c.argv.join(" ") == expected),
            "`{expected}` among {whole:#?}"
        );
    }
    let failed = failures(&commands, parse);
    assert!(
        failed.is_empty(),
        "{} of {} documented sim-client command lines do not parse:\n{}",
        failed.len(),
        commands.len(),
        failed.join("\n")
    );
}

#[test]
fn a_drifted_flag_fails_naming_the_file_and_line() {
    let doc = "Run it:\n\n```sh\nsim-server --world lab &\nsim-client --world lab watch --frame 10 | head -1\n```\n";
    let commands = commands_in("guide.md", doc, "sim-client");
    assert_eq!(commands.len(), 1, "{commands:#?}");
    let failed = failures(&commands, parse);
    assert_eq!(failed.len(), 1, "{failed:#?}");
    assert!(
        failed[0].starts_with("guide.md:5: `sim-client --world lab watch --frame 10`"),
        "{}",
        failed[0]
    );
    assert!(
        failed[0].contains("--frame"),
        "clap's error names the flag: {}",
        failed[0]
    );
}

#[test]
fn shell_syntax_around_a_command_is_not_part_of_it() {
    let doc = concat!(
        "```sh\n",
        "export PATH=$PWD/target/release:$PATH\n",
        "for w in a b; do\n",
        "  RUST_LOG=warn sim-client --world $w watch --digest \\\n",
        "    --frames 3 > $w.digest 2>&1 & watcher=$!   # a comment\n",
        "done\n",
        "python3 - <<'PY'\n",
        "sim-client --world nowhere bogus\n",
        "PY\n",
        "cargo run --release -p sim-client-cli -- status --json\n",
        "```\n",
        "```text\n",
        "$ ./target/release/sim-client demo\n",
        "sim-client: error: not a command\n",
        "```\n",
        "Prose: `sim-client bridge zenoh`, `sim-client --world W foxglove`, `sim-client …`.\n",
    );
    let argvs: Vec<(String, bool)> = commands_in("x.md", doc, "sim-client")
        .into_iter()
        .map(|c| (format!("{} {}", c.place, c.argv.join(" ")), c.fragment))
        .collect();
    assert_eq!(
        argvs,
        [
            (
                "x.md:4 sim-client --world run-a watch --digest --frames 3".to_owned(),
                false
            ),
            ("x.md:10 sim-client status --json".to_owned(), false),
            ("x.md:13 sim-client demo".to_owned(), false),
            ("x.md:16 sim-client bridge zenoh".to_owned(), true),
            ("x.md:16 sim-client --world W foxglove".to_owned(), true),
            ("x.md:16 sim-client".to_owned(), true),
        ]
    );
    let built: Vec<_> = commands_in("x.md", doc, "sim-client")
        .into_iter()
        .filter(|c| built_in(&c.argv))
        .collect();
    assert!(failures(&built, parse).is_empty(), "{built:#?}");
}

#[test]
fn every_flag_in_the_docs_command_tables_exists() {
    let failed = synopsis_failures(&Args::command(), "sim-client");
    assert!(
        failed.is_empty(),
        "{} documented flags that sim-client does not have:\n{}",
        failed.len(),
        failed.join("\n")
    );
}

#[test]
fn a_table_naming_a_flag_a_command_lacks_fails() {
    let doc = concat!(
        "| command | what it does |\n",
        "|---|---|\n",
        "| `watch [--frames N] [--json]` | fine |\n",
        "| `recorder blocked FILE [--min-time S] [--min-seconds S]` | drifted |\n",
        "| `--timeout S` | a global flag, but not under this program's heading |\n",
        "| `ApplyTorque` | not a command |\n",
    );
    let failed = synopses_in("t.md", doc, &Args::command(), "sim-client");
    assert_eq!(failed.len(), 1, "{failed:#?}");
    assert!(
        failed[0].starts_with(
            "t.md:4: `recorder blocked FILE [--min-time S] [--min-seconds S]` names \
             --min-seconds, which `sim-client recorder blocked` does not have"
        ),
        "{}",
        failed[0]
    );
}

#[test]
fn every_chapter_with_rust_code_is_compiled_as_a_doctest() {
    // sim-client/src/lib.rs includes each such chapter as doctests; a new
    // chapter with a ```rust block must be added there to stay true.
    let root = lines::repository_root();
    let library = std::fs::read_to_string(root.join("sim-client/src/lib.rs")).expect("lib.rs");
    for doc in lines::documents(&root) {
        let text = std::fs::read_to_string(root.join(&doc)).expect("a document");
        if text.lines().any(|l| l.trim_start().starts_with("```rust")) {
            let include = format!("include_str!(\"../../{}\")", doc.display());
            assert!(
                library.contains(&include),
                "{} has Rust code: sim-client/src/lib.rs needs #[doc = {include}]",
                doc.display()
            );
        }
    }
}
