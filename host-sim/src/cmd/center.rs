//! `host-sim center`: not built yet.

#[derive(clap::Args, Debug)]
pub struct Args {
    /// Print a JSON summary instead of a table.
    #[arg(long)]
    pub json: bool,
}

pub fn run(_args: Args) -> anyhow::Result<()> {
    anyhow::bail!("`host-sim center` is not implemented yet (see the open issues)")
}
