//! One module per subcommand.

use crate::cli::Command;

/// Runs one parsed command.
pub fn run(command: &Command) -> anyhow::Result<()> {
    let common = command.common();
    let _ = common;
    match command {
        Command::Demo { .. } => not_yet("demo", "the rendering pipeline (issues 3 and 4)"),
        Command::Render { .. } => not_yet("render", "the transport crate (issue 3)"),
        Command::Beamform { .. } => not_yet("beamform", "image formation (issue 4)"),
        Command::Import { .. } => not_yet("import", "image formation (issue 4)"),
        Command::Params { .. } => not_yet("params", "the transport crate (issue 3)"),
        Command::Grad { .. } => not_yet("grad", "end-to-end gradients (issue 5)"),
        Command::Fit { .. } => not_yet("fit", "calibration (issue 5)"),
        Command::Diagnose { .. } => not_yet("diagnose", "the sim-to-real diagnosis (issue 6)"),
    }
}

fn not_yet(command: &str, needs: &str) -> anyhow::Result<()> {
    anyhow::bail!("`usray {command}` is not available in this build yet: it needs {needs}")
}
