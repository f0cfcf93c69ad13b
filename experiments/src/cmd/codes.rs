//! `ifslab codes`: the built-in library.

use ifslab::model::library;

pub fn run() -> anyhow::Result<()> {
    for (name, about) in library::catalogue() {
        let code = library::builtin(name)?;
        println!(
            "{name:<12} {}-D, {} maps  {about}",
            code.dim(),
            code.maps.len()
        );
    }
    Ok(())
}
