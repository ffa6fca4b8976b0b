//! The second `unsafe` room (the first is the Embree binding, `accel::embree`): what the
//! machine offers beyond portable Rust.
//!
//! - Runtime-dispatched SIMD ([`with_avx2`]): the estimator's batch loops compiled a second
//!   time for AVX2 and chosen when the CPU has it. The build itself targets baseline x86-64
//!   (no `target-cpu=native`), so one binary runs everywhere. [`splat_cells`] writes the
//!   diffraction method's splat in AVX2 intrinsics, where the loop vectoriser would
//!   interleave cells.
//! - Memory advice ([`with_huge_pages`]) and software prefetch ([`prefetch`]) for the data
//!   structures whose queries are bound by memory latency (the BRDF kd-tree at 10^6 buckets:
//!   some 30 dependent fetches per query, most of them TLB misses on 4 KiB pages).
//!
//! Each use is a safe wrapper with its SAFETY argument; the rest of the crate calls only
//! these.

/// Runs `f` compiled for AVX2 where the CPU has it, else as compiled for baseline x86-64.
///
/// `f` (a closure, monomorphised per call site) is inlined into a function with the `avx2`
/// target feature, so its loops are vectorised four `f64` lanes wide instead of two. The
/// results are bit-identical either way: Rust never contracts `a * b + c` into a fused
/// multiply-add, and IEEE-754 addition, multiplication, division and square root round
/// the same in every lane width; only the number of lanes per instruction differs
/// (`phase::tests` checks both paths against each other bit for bit). Bodies that call
/// `mul_add` would differ between machines and must not be passed here.
#[inline(always)]
pub fn with_avx2<R>(f: impl FnOnce() -> R) -> R {
    #[cfg(target_arch = "x86_64")]
    {
        #[target_feature(enable = "avx2")]
        fn avx2<R>(f: impl FnOnce() -> R) -> R {
            f()
        }
        if avx2_enabled() {
            // SAFETY: `avx2` only requires the CPU to execute AVX2 instructions, which
            // `avx2_enabled` has just confirmed (`is_x86_feature_detected!`, CPUID).
            return unsafe { avx2(f) };
        }
    }
    f()
}

/// Whether [`with_avx2`] takes its AVX2 path: the CPU has AVX2, and the environment does not
/// set `GONIOSPEC_NO_AVX2` (read once; for tests and benchmarks of the baseline path).
pub fn avx2_enabled() -> bool {
    #[cfg(target_arch = "x86_64")]
    {
        static ON: std::sync::OnceLock<bool> = std::sync::OnceLock::new();
        *ON.get_or_init(|| {
            std::is_x86_feature_detected!("avx2") && std::env::var_os("GONIOSPEC_NO_AVX2").is_none()
        })
    }
    #[cfg(not(target_arch = "x86_64"))]
    false
}

/// Huge pages on x86-64 Linux: 2 MiB.
const HUGE_PAGE: usize = 2 << 20;

/// Below this many bytes an array stays as it is: it spans too few huge pages to matter.
const HUGE_MIN_BYTES: usize = 4 << 20;

/// `v` in memory advised for transparent huge pages, so that its pages are faulted in as 2
/// MiB pages (one TLB entry for 512 of the 4 KiB pages a random walk over it touches).
/// Linux's default (`/sys/kernel/mm/transparent_hugepage/enabled` = `madvise`) grants huge
/// pages only to memory advised with `MADV_HUGEPAGE` before it is first touched, so the
/// elements are copied into a fresh allocation advised first. The 2 MiB-aligned interior of
/// the allocation is advised (its ragged ends keep 4 KiB pages). Arrays under 4 MiB, other
/// systems, and kernels that refuse the advice keep ordinary pages: the contents are the same
/// either way, only the page size differs.
pub fn with_huge_pages<T: Clone>(v: Vec<T>) -> Vec<T> {
    let bytes = std::mem::size_of_val(v.as_slice());
    if bytes < HUGE_MIN_BYTES || !cfg!(target_os = "linux") {
        return v;
    }
    let mut out: Vec<T> = Vec::with_capacity(v.len());
    advise_huge(out.as_ptr().cast(), bytes);
    out.extend_from_slice(&v);
    out
}

/// `madvise(MADV_HUGEPAGE)` over the 2 MiB-aligned interior of `[start, start + bytes)`.
#[cfg(target_os = "linux")]
fn advise_huge(start: *const u8, bytes: usize) {
    let lo = (start as usize).next_multiple_of(HUGE_PAGE);
    let hi = (start as usize + bytes) / HUGE_PAGE * HUGE_PAGE;
    if hi > lo {
        // SAFETY: `[lo, hi)` lies within the allocation behind `start` (the caller's fresh
        // `Vec` with capacity for `bytes` bytes, page-aligned by the allocator's mmap for
        // sizes this large), which this process owns. MADV_HUGEPAGE only changes the size of
        // the pages the kernel backs the range with, never its contents or its validity, so
        // no Rust reference to the memory observes it. The result is advice: a refusal
        // (EINVAL where THP is compiled out) leaves ordinary pages, which is correct too.
        unsafe {
            libc::madvise(lo as *mut libc::c_void, hi - lo, libc::MADV_HUGEPAGE);
        }
    }
}

#[cfg(not(target_os = "linux"))]
fn advise_huge(_start: *const u8, _bytes: usize) {}

/// Asks the CPU to start loading the cache line holding `r` into all cache levels, for a
/// value the caller will read soon (the children of a kd-tree node, before the node's
/// bounds are computed). Does nothing off x86-64.
#[inline(always)]
pub fn prefetch<T>(r: &T) {
    #[cfg(target_arch = "x86_64")]
    // SAFETY: `_mm_prefetch` needs SSE, which every x86-64 CPU has (it is in the x86-64
    // baseline the crate is built for). A prefetch is a hint: it never faults and never
    // changes memory or program state, and `r` is a valid reference besides.
    unsafe {
        core::arch::x86_64::_mm_prefetch::<{ core::arch::x86_64::_MM_HINT_T0 }>(
            (r as *const T).cast::<i8>(),
        );
    }
    #[cfg(not(target_arch = "x86_64"))]
    let _ = r;
}

/// `cells[c][i] += re[i] w_re[c] + im[i] w_im[c]` for every cell `c` of `cells` and each of
/// its twelve reals: the diffraction method's splat of one run of a patch's cells (a
/// complex field of six components times each cell's complex weight, written as two real
/// products). Where the CPU has AVX2 a cell is three 256-bit updates; the loop vectoriser
/// would otherwise run four cells per vector and spend the gain on shuffles. The same
/// products and sums in the same order either way, no fused multiply-add: the same bits
/// (tested below).
#[inline(always)]
pub fn splat_cells(
    cells: &mut [[f64; 12]],
    w_re: &[f64],
    w_im: &[f64],
    re: &[f64; 12],
    im: &[f64; 12],
) {
    assert!(w_re.len() >= cells.len() && w_im.len() >= cells.len());
    #[cfg(target_arch = "x86_64")]
    if avx2_enabled() {
        // SAFETY: `splat_avx2` only requires the CPU to execute AVX2 instructions, which
        // `avx2_enabled` has confirmed; its pointer accesses stay inside `cells`, `re` and
        // `im` (below).
        unsafe { splat_avx2(cells, w_re, w_im, re, im) };
        return;
    }
    splat_portable(cells, w_re, w_im, re, im);
}

#[inline(always)]
fn splat_portable(
    cells: &mut [[f64; 12]],
    w_re: &[f64],
    w_im: &[f64],
    re: &[f64; 12],
    im: &[f64; 12],
) {
    for ((cell, &wr), &wi) in cells.iter_mut().zip(w_re).zip(w_im) {
        for i in 0..12 {
            cell[i] += re[i] * wr + im[i] * wi;
        }
    }
}

#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "avx2")]
fn splat_avx2(cells: &mut [[f64; 12]], w_re: &[f64], w_im: &[f64], re: &[f64; 12], im: &[f64; 12]) {
    use core::arch::x86_64::{
        _mm256_add_pd, _mm256_loadu_pd, _mm256_mul_pd, _mm256_set1_pd, _mm256_storeu_pd,
    };
    // SAFETY (every load and store below): the pointers are to `[f64; 12]` arrays, read and
    // written four doubles at offsets 0, 4 and 8, inside the array; `loadu`/`storeu` take
    // any alignment.
    let (r, m) = unsafe {
        (
            [0, 4, 8].map(|k| _mm256_loadu_pd(re.as_ptr().add(k))),
            [0, 4, 8].map(|k| _mm256_loadu_pd(im.as_ptr().add(k))),
        )
    };
    for ((cell, &wr), &wi) in cells.iter_mut().zip(w_re).zip(w_im) {
        let (a, b) = (_mm256_set1_pd(wr), _mm256_set1_pd(wi));
        let p = cell.as_mut_ptr();
        for k in 0..3 {
            let t = _mm256_add_pd(_mm256_mul_pd(r[k], a), _mm256_mul_pd(m[k], b));
            // SAFETY: as above, offsets 0, 4 and 8 of a `[f64; 12]`.
            unsafe {
                let c = _mm256_loadu_pd(p.add(4 * k));
                _mm256_storeu_pd(p.add(4 * k), _mm256_add_pd(c, t));
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The splat's AVX2 path gives the portable path's bits.
    #[test]
    fn the_splat_is_the_same_bits_either_way() {
        let re: [f64; 12] = std::array::from_fn(|i| (i as f64 * 0.37).sin() * 1e-3);
        let im: [f64; 12] = std::array::from_fn(|i| (i as f64 * 1.13).cos() * 3e-4);
        let w_re: Vec<f64> = (0..37).map(|i| (i as f64 * 0.71).cos() * 0.3).collect();
        let w_im: Vec<f64> = (0..37).map(|i| (i as f64 * 0.29).sin() * 0.7).collect();
        let start: Vec<[f64; 12]> = (0..37)
            .map(|c| std::array::from_fn(|i| (c * 12 + i) as f64 * 1e-5 - 1e-3))
            .collect();
        let mut a = start.clone();
        splat_portable(&mut a, &w_re, &w_im, &re, &im);
        let mut b = start.clone();
        splat_cells(&mut b, &w_re, &w_im, &re, &im);
        assert_ne!(a, start);
        assert_eq!(
            a.iter().flatten().map(|x| x.to_bits()).collect::<Vec<_>>(),
            b.iter().flatten().map(|x| x.to_bits()).collect::<Vec<_>>()
        );
    }

    /// The copy keeps every element and the length; small arrays are returned as they are.
    #[test]
    fn huge_pages_keep_the_contents() {
        let big: Vec<u64> = (0..(3 << 20)).map(|i| i * 7 + 1).collect();
        let copy = with_huge_pages(big.clone());
        assert_eq!(copy, big);
        let small = vec![1u32, 2, 3];
        let p = small.as_ptr();
        let same = with_huge_pages(small);
        assert_eq!(same.as_ptr(), p);
        prefetch(&same[1]);
        assert_eq!(same, [1, 2, 3]);
    }

    /// Where the kernel grants transparent huge pages on advice (`madvise` or `always` in
    /// /sys/kernel/mm/transparent_hugepage/enabled), a 64 MiB array copied through
    /// [`with_huge_pages`] is backed by at least 16 MiB more of them (this process's
    /// AnonHugePages in /proc/self/smaps_rollup). Skipped, saying so, where THP is off.
    #[test]
    fn advised_arrays_get_huge_pages_where_the_kernel_grants_them() {
        let Ok(mode) = std::fs::read_to_string("/sys/kernel/mm/transparent_hugepage/enabled")
        else {
            eprintln!("no transparent huge pages on this system: skipped");
            return;
        };
        if mode.contains("[never]") {
            eprintln!("transparent huge pages are off ({mode:?}): skipped");
            return;
        }
        let huge_kb = || -> u64 {
            std::fs::read_to_string("/proc/self/smaps_rollup")
                .unwrap()
                .lines()
                .find_map(|l| l.strip_prefix("AnonHugePages:"))
                .and_then(|v| v.trim().trim_end_matches("kB").trim().parse().ok())
                .unwrap_or(0)
        };
        let before = huge_kb();
        let v = with_huge_pages(vec![3u8; 64 << 20]);
        let after = huge_kb();
        assert!(
            after >= before + (16 << 10),
            "AnonHugePages {before} kB -> {after} kB"
        );
        assert!(v.iter().all(|&b| b == 3));
    }
}
