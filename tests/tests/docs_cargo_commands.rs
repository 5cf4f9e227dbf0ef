//! Every `cargo` command the README and the book give reuses the first
//! build: a `cargo build` or `cargo run` resolves, crate by crate, the
//! features the README's `cargo build --release` (the whole workspace)
//! resolves, and a `cargo test` those of `cargo test --workspace`, so none
//! of them builds rapier3d, iceoryx2 or the server a second time. (It did:
//! the performance chapter's `cargo run --release -p simbus-bench -- ...`
//! resolved other features than the workspace build, and cargo built a
//! second copy of the heavy crates, minutes on two cores.)
//!
//! The README's first command builds less (the two binaries without the
//! adapters, in minutes on a fresh clone), but every crate it compiles
//! with the features the whole workspace's build gives it, so the `cargo
//! build --release` after it reuses all of them: only the `sim-client`
//! binary itself, built without its adapters, is built again.
//!
//! Nothing is built or timed: `cargo tree` prints each package with the
//! features a command would build it with, which is what names its
//! artifacts (their file names are the same when these are).

use std::collections::BTreeSet;
use std::path::{Path, PathBuf};
use std::process::Command;

/// The repository's root.
fn root() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR"))
        .parent()
        .expect("tests/ is inside the repository")
        .to_path_buf()
}

/// README.md and every chapter of the book.
fn documents() -> Vec<PathBuf> {
    let mut paths = vec![root().join("README.md")];
    let book = root().join("docs/src");
    let mut chapters: Vec<_> = std::fs::read_dir(&book)
        .unwrap_or_else(|e| panic!("{}: {e}", book.display()))
        .filter_map(|entry| entry.ok().map(|e| e.path()))
        .filter(|p| p.extension().is_some_and(|x| x == "md"))
        .collect();
    chapters.sort();
    paths.extend(chapters);
    paths
}

/// The code a reader copies from `text`: inline code spans (which may wrap
/// over lines) and the lines of fenced blocks.
fn code_in(text: &str) -> Vec<String> {
    let mut code = Vec::new();
    let mut fenced = false;
    let mut prose = String::new();
    for line in text.lines() {
        if line.trim_start().starts_with("```") {
            fenced = !fenced;
            prose.push('\n');
            continue;
        }
        if fenced {
            code.push(line.to_owned());
        } else {
            prose.push_str(line);
            prose.push('\n');
        }
    }
    code.extend(
        prose
            .split('`')
            .skip(1)
            .step_by(2)
            .map(|span| span.split_whitespace().collect::<Vec<_>>().join(" ")),
    );
    code
}

/// One `cargo` command: its words after `cargo`.
#[derive(Debug, Clone, PartialEq, Eq, PartialOrd, Ord)]
struct CargoCommand(Vec<String>);

impl CargoCommand {
    /// The cargo subcommand (`build`, `run`, `test`, ...).
    fn subcommand(&self) -> &str {
        self.0.first().map_or("", String::as_str)
    }

    /// The packages it selects with `-p` / `--package`.
    fn packages(&self) -> Vec<&str> {
        let mut packages = Vec::new();
        let mut words = self.0.iter().take_while(|w| *w != "--");
        while let Some(word) = words.next() {
            if let Some(p) = word.strip_prefix("--package=") {
                packages.push(p);
            } else if word == "-p" || word == "--package" {
                packages.extend(words.next().map(String::as_str));
            }
        }
        packages
    }

    /// Whether it chooses its own features (a build that is meant to
    /// differ, as the architecture chapter's adapter-less `sim-client`).
    fn chooses_features(&self) -> bool {
        self.0
            .iter()
            .any(|w| w == "--no-default-features" || w.starts_with("--features"))
    }
}

/// Every `cargo` command in `code`, a shell line split at `&&` and `;`.
fn cargo_commands(code: &str) -> Vec<CargoCommand> {
    code.split("&&")
        .flat_map(|part| part.split(';'))
        .filter_map(|part| {
            let mut words = part.split_whitespace();
            (words.next() == Some("cargo"))
                .then(|| CargoCommand(words.map(str::to_owned).collect()))
        })
        .collect()
}

/// Every `cargo` command in the README and the book.
fn documented() -> BTreeSet<CargoCommand> {
    documents()
        .iter()
        .flat_map(|path| {
            let text =
                std::fs::read_to_string(path).unwrap_or_else(|e| panic!("{}: {e}", path.display()));
            code_in(&text)
        })
        .flat_map(|code| cargo_commands(&code))
        .collect()
}

/// Each package a build of `selection` compiles, with its features, as
/// `cargo tree` prints them; `tests`: with the dev-dependencies a `cargo
/// test` adds.
fn resolved(selection: &[&str], tests: bool) -> BTreeSet<String> {
    let cargo = std::env::var("CARGO").unwrap_or_else(|_| "cargo".to_owned());
    let edges = if tests {
        "normal,build,dev"
    } else {
        "normal,build"
    };
    let output = Command::new(&cargo)
        .current_dir(root())
        .args([
            "tree",
            "--offline",
            "--prefix",
            "none",
            "-f",
            "{p}|{f}",
            "-e",
            edges,
        ])
        .args(selection)
        .output()
        .unwrap_or_else(|e| panic!("running {cargo} tree: {e}"));
    assert!(
        output.status.success(),
        "cargo tree {selection:?} failed: {}",
        String::from_utf8_lossy(&output.stderr)
    );
    String::from_utf8_lossy(&output.stdout)
        .lines()
        .map(|line| line.trim_end_matches(" (*)").to_owned())
        .filter(|line| !line.is_empty())
        .collect()
}

/// The arguments of `command` that choose what `cargo tree` resolves: its
/// packages and its features.
fn selection_of(command: &CargoCommand) -> Vec<String> {
    let mut selection = Vec::new();
    let mut words = command.0.iter().take_while(|w| *w != "--");
    while let Some(word) = words.next() {
        match word.as_str() {
            "-p" | "--package" | "-F" | "--features" => {
                selection.push(word.clone());
                selection.extend(words.next().cloned());
            }
            "--no-default-features" | "--all-features" => selection.push(word.clone()),
            w if w.starts_with("--package=") || w.starts_with("--features=") => {
                selection.push(word.clone());
            }
            _ => {}
        }
    }
    selection
}

/// The README's first command: the one that builds the demo.
fn first_command() -> CargoCommand {
    let readme = std::fs::read_to_string(root().join("README.md")).expect("README.md");
    let demo = readme
        .split("**Run the demo**")
        .nth(1)
        .expect("the README has a **Run the demo** paragraph");
    code_in(demo)
        .iter()
        .flat_map(|code| cargo_commands(code))
        .next()
        .expect("a cargo command under **Run the demo**")
}

/// Whether the package of a `cargo tree` line builds only binaries (no
/// library another build could reuse).
fn binaries_only(unit: &str) -> bool {
    let Some(path) = unit
        .split_once(" (")
        .and_then(|(_, rest)| rest.split_once(')'))
        .map(|(path, _)| PathBuf::from(path))
    else {
        return false;
    };
    path.join("Cargo.toml").exists() && !path.join("src/lib.rs").exists()
}

#[test]
fn the_first_command_builds_every_library_as_the_workspace_build_does() {
    let first = first_command();
    assert_eq!(first.subcommand(), "build", "{first:?}");
    assert!(first.0.iter().any(|w| w == "--release"), "{first:?}");
    let selection = selection_of(&first);
    let selection: Vec<&str> = selection.iter().map(String::as_str).collect();
    let workspace = resolved(&["--workspace"], false);
    let built = resolved(&selection, false);
    assert!(
        built.iter().any(|u| u.starts_with("sim-server "))
            && built.iter().any(|u| u.starts_with("rapier3d ")),
        "the first command builds the server and the physics: {built:#?}"
    );
    let again: Vec<_> = built
        .iter()
        .filter(|unit| !workspace.contains(*unit) && !binaries_only(unit))
        .collect();
    assert!(
        again.is_empty(),
        "`cargo {}` builds these with other features than `cargo build --release`, \
         which would compile them (and what depends on them) again: {again:#?}; \
         pin the features in sim-client/cli/Cargo.toml",
        first.0.join(" ")
    );
}

/// `pip install ./sim-client/python` (the README's next step for Python)
/// builds the extension with maturin: a build of its package alone, which
/// must compile every crate as the workspace's build does, so it reuses
/// what the first command and `cargo build --release` compiled.
#[test]
fn the_python_package_builds_every_crate_as_the_workspace_build_does() {
    let workspace = resolved(&["--workspace"], false);
    let built = resolved(&["-p", "simbus-python"], false);
    assert!(
        built.iter().any(|u| u.starts_with("sim-client ")),
        "the extension builds the client library: {built:#?}"
    );
    let again: Vec<_> = built
        .iter()
        .filter(|unit| !workspace.contains(*unit))
        .collect();
    assert!(
        again.is_empty(),
        "the Python package builds these with other features than the workspace: {again:#?}; \
         pin the features in sim-client/python/Cargo.toml"
    );
}

/// The first command's check sees a build whose features differ: without
/// the pins in the command line's manifest, the server's build without
/// the adapters resolves other features for the crates it shares.
#[test]
fn a_build_without_the_pins_is_seen_to_differ() {
    let workspace = resolved(&["--workspace"], false);
    let built = resolved(&["-p", "sim-server", "--no-default-features"], false);
    assert!(
        built
            .iter()
            .any(|u| !workspace.contains(u) && !binaries_only(u)),
        "a server library without its command line now resolves the workspace's features"
    );
}

/// What `command` would build that the first build did not: each package
/// whose features differ from the workspace's (empty when it reuses it).
fn rebuilt(command: &CargoCommand) -> Vec<String> {
    let packages = command.packages();
    if packages.is_empty() {
        // No selection: the whole workspace (no default-members).
        return Vec::new();
    }
    let tests = command.subcommand() == "test";
    let first = resolved(&["--workspace"], tests);
    let selection: Vec<&str> = packages.iter().flat_map(|p| ["-p", *p]).collect();
    resolved(&selection, tests)
        .into_iter()
        .filter(|unit| !first.contains(unit))
        .collect()
}

#[test]
fn every_cargo_command_in_the_docs_reuses_the_first_build() {
    let commands = documented();
    // The extraction finds what a reader runs first (a test that finds
    // nothing proves nothing).
    for expected in [["build", "--release"], ["test", "--workspace"]] {
        let expected = CargoCommand(expected.map(str::to_owned).to_vec());
        assert!(
            commands.contains(&expected),
            "`cargo {}` not found among {commands:#?}",
            expected.0.join(" ")
        );
    }
    let mut failures = Vec::new();
    for command in &commands {
        if !matches!(command.subcommand(), "build" | "run" | "test") || command.chooses_features() {
            continue;
        }
        let rebuilt = rebuilt(command);
        if !rebuilt.is_empty() {
            failures.push(format!(
                "`cargo {}` builds {} package(s) with other features than the workspace \
                 build, e.g. {:?}: give the built binary (target/release/...) or no -p",
                command.0.join(" "),
                rebuilt.len(),
                &rebuilt[..rebuilt.len().min(3)]
            ));
        }
    }
    assert!(failures.is_empty(), "{}", failures.join("\n"));
}

/// The check sees what the issue saw: `cargo run -p simbus-bench` resolves
/// other features than `cargo build --release` (so the docs give
/// `target/release/simbus-bench`).
#[test]
fn a_build_of_one_package_is_seen_to_resolve_other_features() {
    let command = CargoCommand(
        ["run", "--release", "-p", "simbus-bench", "--", "tick"]
            .map(str::to_owned)
            .to_vec(),
    );
    assert_eq!(command.packages(), ["simbus-bench"]);
    let rebuilt = rebuilt(&command);
    assert!(
        !rebuilt.is_empty(),
        "cargo run -p simbus-bench now resolves the workspace's features: \
         the docs may give it again"
    );
}

#[test]
fn commands_are_found_in_code_spans_that_wrap_and_in_fenced_blocks() {
    let text = "Run `cargo build --release -p\nsimbus-bench && target/x`.\n\n\
                ```sh\ncargo test --workspace\n```\nnot `code`";
    let found: Vec<_> = code_in(text)
        .iter()
        .flat_map(|c| cargo_commands(c))
        .collect();
    assert_eq!(
        found,
        [
            CargoCommand(vec!["test".into(), "--workspace".into()]),
            CargoCommand(
                ["build", "--release", "-p", "simbus-bench"]
                    .map(str::to_owned)
                    .to_vec()
            ),
        ]
    );
}
