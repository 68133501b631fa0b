//! Command-line flags every role shares (behind the `cli` feature, so the wire crate stays plain data for
//! anyone who links it without clap).
//!
//! Owns: the `--emulate-*` flags, which turn into an [`EmulationConfig`] on what the role publishes (a
//! server's force commands, a hapticserver's poses).

use crate::rt::EmulationConfig;

/// `--emulate-delay-ms`, `--emulate-jitter-ms`, `--emulate-loss`, `--emulate-seed`: `#[command(flatten)]` them
/// into a role's arguments.
#[derive(Debug, Clone, Copy, PartialEq, clap::Args)]
pub struct EmulationArgs {
    /// Emulate a distant site: delay every message this role publishes on the haptic path (a server's force
    /// commands, a hapticserver's poses) by this much, ms.
    #[arg(long, default_value_t = 0.0)]
    pub emulate_delay_ms: f64,
    /// Vary each emulated delay uniformly by up to this much either way, ms (order is kept).
    #[arg(long, default_value_t = 0.0)]
    pub emulate_jitter_ms: f64,
    /// Lose this fraction of those messages (0..1), seeded by --emulate-seed.
    #[arg(long, default_value_t = 0.0)]
    pub emulate_loss: f64,
    /// Seed of the emulated loss and jitter.
    #[arg(long, default_value_t = 1)]
    pub emulate_seed: u64,
}

impl EmulationArgs {
    /// The emulation these flags ask for, checked: a clear message for a negative delay, a loss outside 0..1,
    /// or a non-finite value.
    pub fn config(&self) -> Result<EmulationConfig, String> {
        let config = EmulationConfig {
            delay_ms: self.emulate_delay_ms,
            jitter_ms: self.emulate_jitter_ms,
            loss: self.emulate_loss,
            seed: self.emulate_seed,
        };
        config.validate().map(|()| config)
    }
}

#[cfg(test)]
mod tests {
    use clap::Parser;

    use super::*;

    #[derive(Debug, Parser)]
    struct Role {
        #[command(flatten)]
        emulation: EmulationArgs,
    }

    #[test]
    fn flags_become_a_checked_emulation() {
        let role = Role::try_parse_from([
            "role",
            "--emulate-delay-ms",
            "50",
            "--emulate-jitter-ms",
            "10",
            "--emulate-loss",
            "0.05",
            "--emulate-seed",
            "7",
        ])
        .unwrap();
        let config = role.emulation.config().unwrap();
        assert_eq!(
            config,
            EmulationConfig {
                delay_ms: 50.0,
                jitter_ms: 10.0,
                loss: 0.05,
                seed: 7
            }
        );
        let off = Role::try_parse_from(["role"]).unwrap();
        assert!(off.emulation.config().unwrap().is_off());
        let bad = Role::try_parse_from(["role", "--emulate-loss", "1.5"]).unwrap();
        assert!(bad.emulation.config().unwrap_err().contains("loss"));
    }
}
