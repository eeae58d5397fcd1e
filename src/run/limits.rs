//! Fitting the memory budget to the machine's limits: the address-space limit (`ulimit -v`,
//! against which the memory-mapped inputs and every thread's stack count) and the cgroup's
//! memory limit (a container's, a batch job's). A budget above what a limit leaves is lowered
//! with a message; a limit that leaves less than the smallest budget is refused, naming it. An
//! allocation past a limit aborts the process (exit 134, nothing the tool can catch), so this
//! is checked before any work.

use crate::config::ExecOptions;
use crate::core::plan::{fit_budget, BudgetFit, MIN_BUDGET_BYTES};
use crate::error::{Error, Result};
use crate::io::limits::{address_space_limit, cgroup_memory_limit};
use crate::progress::Reporter;
use crate::run::spec::RunSpec;

/// What the program takes besides its budget, its inputs and its threads' stacks: code,
/// libraries, the allocator's own. Measured: a run of the shipped sample (22k points) needs 31
/// MiB of address space; a run of 2M points with `--memory 64M` 66 MiB beside its mapped
/// input, with `--memory 256M` 146 MiB (the allocator in one arena, as under a limit).
const PROGRAM_BYTES: u64 = 32 << 20;

/// The address space of one thread's stack besides the run's workers (Rust's and rayon's
/// default size); the workers have [`super::WORKER_STACK`].
const STACK_BYTES: u64 = 2 << 20;

const MIB: u64 = 1 << 20;

/// The budget for a run of `spec` as `exec` asks: `--memory`, lowered to what the address-space
/// limit and the cgroup's memory limit leave, with a message; a usage error (exit 2) naming the
/// limit and what to raise it to when it cannot hold even the smallest budget.
pub(crate) fn fit_memory(
    exec: &ExecOptions,
    spec: &RunSpec,
    reporter: &dyn Reporter,
) -> Result<u64> {
    let mapped: u64 = spec
        .sources
        .iter()
        .map(|s| std::fs::metadata(s.path()).map_or(0, |m| m.len()))
        .sum();
    // The run's pool and the tile drivers' own workers (large stacks), rayon's global pool
    // (the LAZ compressor's), the tile drivers (one per thread, at least 2), the rest.
    let cores = std::thread::available_parallelism().map_or(1, |n| n.get()) as u64;
    let threads = exec.threads as u64;
    // LAZ inputs are decoded on threads whose stacks bound the codec's recursion
    // (`io/las/decode.rs`), present during the scan only.
    let laz = spec.sources.iter().any(
        |s| matches!(s.layout(), crate::io::source::SourceLayout::Las(p) if p.header.compressed),
    );
    let decoding = if laz {
        threads * crate::io::las::decode::DECODE_STACK as u64
    } else {
        0
    };
    let own = PROGRAM_BYTES
        + 2 * threads * super::WORKER_STACK as u64
        + (cores + threads.max(2) + 2) * STACK_BYTES
        + decoding;
    let mut budget = exec.memory_bytes;
    if let Some(limit) = address_space_limit() {
        let besides = format!(
            "the mapped inputs take {} MiB and tilecurv {} MiB besides its budget",
            mapped.div_ceil(MIB),
            own.div_ceil(MIB)
        );
        let kib = |b: u64| b.div_ceil(1024);
        budget = fit(
            budget,
            limit,
            mapped + own,
            "the address-space limit (ulimit -v)",
            &besides,
            &|need| format!("`ulimit -v {}` or more, or unlimited", kib(need)),
            reporter,
        )?;
    }
    if let Some(crate::io::limits::MemoryLimit { bytes: limit, file }) = cgroup_memory_limit() {
        let name = format!("the memory limit of this cgroup ({})", file.display());
        let besides = format!(
            "tilecurv takes {} MiB besides its budget",
            own.div_ceil(MIB)
        );
        budget = fit(
            budget,
            limit,
            own,
            &name,
            &besides,
            &|need| {
                format!(
                    "{} MiB or more (a job's memory request)",
                    need.div_ceil(MIB)
                )
            },
            reporter,
        )?;
    }
    Ok(budget)
}

/// Fits `budget` into one limit named `name`, of which `taken` bytes go to other things (said
/// by `besides`); `raise` says what to raise the limit to.
fn fit(
    budget: u64,
    limit: u64,
    taken: u64,
    name: &str,
    besides: &str,
    raise: &dyn Fn(u64) -> String,
    reporter: &dyn Reporter,
) -> Result<u64> {
    match fit_budget(budget, limit, taken) {
        BudgetFit::Fits => Ok(budget),
        BudgetFit::Lowered(lower) => {
            reporter.warn(&format!(
                "--memory {} MiB does not fit {name} of {} MiB ({besides}): using --memory {}M",
                budget / MIB,
                limit / MIB,
                lower / MIB
            ));
            Ok(lower)
        }
        BudgetFit::TooSmall(need) => Err(Error::Usage(format!(
            "{name} of {} MiB is too small for this run: {besides}, and the smallest budget (--memory {}M) {} MiB more; raise it to {}",
            limit / MIB,
            MIN_BUDGET_BYTES / MIB,
            MIN_BUDGET_BYTES / MIB,
            raise(need)
        ))),
    }
}
