//! `goniospec-fuzz TARGET`: the AFL entry point (persistent mode) for one parser. Built
//! by `cargo afl build` (which sets `--cfg fuzzing`); a plain build reads one input from
//! standard input instead, to reproduce a finding: `goniospec-fuzz obj < crash`.

fn main() {
    let name = std::env::args().nth(1).unwrap_or_default();
    let Some(f) = goniospec_fuzz::target(&name) else {
        let names: Vec<&str> = goniospec_fuzz::TARGETS.iter().map(|(n, _)| *n).collect();
        eprintln!("usage: goniospec-fuzz TARGET ({})", names.join(", "));
        std::process::exit(2);
    };
    #[cfg(fuzzing)]
    afl::fuzz!(|data: &[u8]| f(data));
    #[cfg(not(fuzzing))]
    {
        use std::io::Read;
        let mut data = Vec::new();
        std::io::stdin()
            .read_to_end(&mut data)
            .expect("reading standard input");
        f(&data);
    }
}
