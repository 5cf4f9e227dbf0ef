//! Every `sim-server …` command line in README.md and the book
//! (`docs/src/**/*.md`) parses with this binary's own clap definitions, so
//! a renamed or removed flag fails the suite until the documentation
//! follows. The lines are found as `sim-client`'s are, by the same code.

#[path = "../../sim-client/cli/src/doc_commands/lines.rs"]
#[allow(dead_code)] // sim-client's half uses the rest
mod lines;

use clap::{CommandFactory, Parser};

use crate::cli::ServerArgs as Args;
use lines::{failures, in_the_docs, synopsis_failures};

#[test]
fn every_sim_server_command_line_in_the_docs_parses() {
    let commands = in_the_docs("sim-server");
    let whole: Vec<_> = commands.iter().filter(|c| !c.fragment).collect();
    // The extraction finds what a reader copies (a test that finds nothing
    // proves nothing): the tour's server and the recipe's.
    assert!(
        whole.len() >= 5,
        "{} command lines: {whole:#?}",
        whole.len()
    );
    for expected in [
        "sim-server --world lab --scene default --delta-seconds 0.05 --realtime",
        "sim-server --world run-a --sync --seed 7 --delta-seconds 0.02",
    ] {
        assert!(
            whole.iter().any(|c| c.argv.join(" ") == expected),
            "`{expected}` among {whole:#?}"
        );
    }
    let failed = failures(&commands, |argv| Args::try_parse_from(argv).map(drop));
    assert!(
        failed.is_empty(),
        "{} of {} documented sim-server command lines do not parse:\n{}",
        failed.len(),
        commands.len(),
        failed.join("\n")
    );
}

#[test]
fn every_flag_in_the_docs_flag_table_exists() {
    let failed = synopsis_failures(&Args::command(), "sim-server");
    assert!(
        failed.is_empty(),
        "{} documented flags that sim-server does not have:\n{}",
        failed.len(),
        failed.join("\n")
    );
}
