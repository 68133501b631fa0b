//! Command-line options shared by the bench binaries (after `--`).

/// The value of `--<name> N`, or `default` when it is not given; an error when N is not a count.
pub fn count_arg(name: &str, default: usize) -> Result<usize, std::num::ParseIntError> {
    let args: Vec<String> = std::env::args().collect();
    let flag = format!("--{name}");
    args.iter()
        .position(|a| *a == flag)
        .and_then(|i| args.get(i + 1))
        .map_or(Ok(default), |s| s.parse())
}

/// The value of `--<name> TEXT`, if given.
#[allow(dead_code)] // not every bench takes a text option
pub fn text_arg(name: &str) -> Option<String> {
    let args: Vec<String> = std::env::args().collect();
    let flag = format!("--{name}");
    args.iter()
        .position(|a| *a == flag)
        .and_then(|i| args.get(i + 1))
        .cloned()
}
