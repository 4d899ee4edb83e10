//! An instruction clock for QEMU: SysTick on the core clock, read under `-icount shift=0`.
//!
//! With `-icount shift=0` QEMU advances its virtual clock by exactly 1 ns per guest
//! instruction, and drives SysTick's core clock (the mps2 boards' 25 MHz SYSCLK) from that
//! virtual clock, so one tick is 40 ns of virtual time: 40 instructions. A reading is
//! therefore an instruction count to within one tick, independent of the host's speed and
//! load; it says nothing about the cycles of a real Cortex-M4 (QEMU models no pipeline,
//! wait states or caches). [`InsnClock::calibrate`] checks the 40 against a loop of known
//! length, so a run without `-icount` fails instead of printing host time.

use cortex_m::peripheral::{SYST, syst::SystClkSource};

/// Guest instructions per SysTick tick: 1 ns per instruction, 25 MHz core clock.
pub const INSNS_PER_TICK: u64 = 40;

/// SysTick counts down from this (its 24-bit maximum) and wraps to it.
const RELOAD: u32 = 0x00ff_ffff;

/// Why a measurement cannot be trusted.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum ClockError {
    /// More than 2^24 ticks passed: the counter wrapped.
    Wrapped,
    /// The calibration loop did not take [`INSNS_PER_TICK`] instructions per tick (QEMU
    /// was not started with `-icount shift=0`): `(loop instructions, ticks read)`.
    NotIcount(u64, u64),
}

impl core::fmt::Display for ClockError {
    fn fmt(&self, f: &mut core::fmt::Formatter<'_>) -> core::fmt::Result {
        match self {
            Self::Wrapped => f.write_str("SysTick wrapped (over 2^24 ticks)"),
            Self::NotIcount(insns, ticks) => write!(
                f,
                "a {insns}-instruction loop read {ticks} ticks, not {}: run QEMU with -icount shift=0",
                insns / INSNS_PER_TICK
            ),
        }
    }
}

/// SysTick, owned and free-running on the core clock.
pub struct InsnClock {
    syst: SYST,
}

impl core::fmt::Debug for InsnClock {
    fn fmt(&self, f: &mut core::fmt::Formatter<'_>) -> core::fmt::Result {
        f.debug_struct("InsnClock").finish_non_exhaustive()
    }
}

impl InsnClock {
    /// Takes SysTick over: core clock, full reload, no interrupt.
    #[must_use]
    pub fn new(mut syst: SYST) -> Self {
        syst.disable_interrupt();
        syst.set_clock_source(SystClkSource::Core);
        syst.set_reload(RELOAD);
        Self { syst }
    }

    /// Runs `f` from a freshly reloaded counter; returns its result and the instructions
    /// it took. Inside `f`, [`InsnClock::since_start`] reads the running count.
    ///
    /// # Errors
    /// [`ClockError::Wrapped`] if `f` took more than 2^24 ticks (671 million instructions).
    pub fn measure<T>(&mut self, f: impl FnOnce() -> T) -> Result<(T, u64), ClockError> {
        self.syst.disable_counter();
        self.syst.clear_current();
        let _ = self.syst.has_wrapped(); // clears COUNTFLAG
        self.syst.enable_counter();
        let value = f();
        let ticks = Self::since_start();
        self.syst.disable_counter();
        if self.syst.has_wrapped() {
            return Err(ClockError::Wrapped);
        }
        Ok((value, ticks))
    }

    /// Instructions since the current [`InsnClock::measure`] began (meaningful only inside
    /// it, and only below 2^24 ticks).
    #[must_use]
    pub fn since_start() -> u64 {
        u64::from(RELOAD - SYST::get_current().min(RELOAD)) * INSNS_PER_TICK
    }

    /// Times `cortex_m::asm::delay(1_000_000)`: in cortex-m 0.7.10 (pinned by Cargo.lock) a
    /// `subs`/`bne` loop of `n + 1` iterations, 2 000 002 instructions. Checks the reading
    /// within 1 % and returns it.
    ///
    /// # Errors
    /// [`ClockError::NotIcount`] if it is off, [`ClockError::Wrapped`] if far off.
    pub fn calibrate(&mut self) -> Result<u64, ClockError> {
        const N: u32 = 1_000_000;
        const LOOP_INSNS: u64 = 2 * (N as u64 + 1);
        let ((), insns) = self.measure(|| cortex_m::asm::delay(N))?;
        if insns.abs_diff(LOOP_INSNS) > LOOP_INSNS / 100 {
            return Err(ClockError::NotIcount(LOOP_INSNS, insns / INSNS_PER_TICK));
        }
        Ok(insns)
    }
}
