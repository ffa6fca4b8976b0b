//! The second `unsafe` room (the first is the Embree binding, `accel::embree`): what the
//! machine offers beyond portable Rust.
//!
//! - Runtime-dispatched SIMD ([`with_avx2`]): the estimator's batch loops compiled a second
//!   time for AVX2 and chosen when the CPU has it. The build itself targets baseline x86-64
//!   (no `target-cpu=native`), so one binary runs everywhere. [`splat_cells`] and
//!   [`row_weights`] write the diffraction method's splat and its patches' weights in AVX2
//!   intrinsics, where the loop vectoriser would interleave cells or leave the lanes scalar.
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

/// A run of a patch's cells along one grid row, within the tile.
#[derive(Clone, Copy, Debug)]
pub struct Run {
    /// The run's first cell, an index into the grid's cells.
    pub cell: usize,
    /// Its first weight, an index into the weights (each holding four rows' side by side).
    pub weight: usize,
    /// Its number of cells.
    pub len: usize,
    /// Which of the four rows' weights is this run's, 0 to 3.
    pub lane: usize,
}

/// `cells[cell + c][i] += re[i] w_re[weight + c][lane] + im[i] w_im[weight + c][lane]` for
/// every [`Run`] of `runs`, every `c < len` and each of a cell's twelve reals (the
/// weights of four rows side by side, this row's in `lane`): the diffraction method's splat
/// of one patch (a complex field of six components times each cell's complex weight,
/// written as two real products). Where the CPU has AVX2 a cell is three 256-bit updates;
/// the loop vectoriser would otherwise run four cells per vector and spend the gain on
/// shuffles. The same products and sums in the same order either way, no fused
/// multiply-add: the same bits (tested below).
///
/// Panics where a run reaches beyond `cells` or the weights, or its lane beyond 3.
#[inline(always)]
pub fn splat_cells(
    cells: &mut [[f64; 12]],
    runs: &[Run],
    w_re: &[[f64; 4]],
    w_im: &[[f64; 4]],
    re: &[f64; 12],
    im: &[f64; 12],
) {
    #[cfg(target_arch = "x86_64")]
    if avx2_enabled() {
        // SAFETY: `splat_avx2` only requires the CPU to execute AVX2 instructions, which
        // `avx2_enabled` has confirmed; its pointer accesses stay inside `cells`, `re` and
        // `im` (below).
        unsafe { splat_avx2(cells, runs, w_re, w_im, re, im) };
        return;
    }
    splat_portable(cells, runs, w_re, w_im, re, im);
}

/// One run's cells and weights, checked against their slices.
#[inline(always)]
#[allow(clippy::type_complexity)]
fn run_slices<'a>(
    cells: &'a mut [[f64; 12]],
    &Run {
        cell: c0,
        weight: w0,
        len: n,
        lane,
    }: &Run,
    w_re: &'a [[f64; 4]],
    w_im: &'a [[f64; 4]],
) -> (&'a mut [[f64; 12]], &'a [[f64; 4]], &'a [[f64; 4]], usize) {
    assert!(lane < 4, "a run's lane is one of four");
    (
        &mut cells[c0..c0 + n],
        &w_re[w0..w0 + n],
        &w_im[w0..w0 + n],
        lane,
    )
}

fn splat_portable(
    cells: &mut [[f64; 12]],
    runs: &[Run],
    w_re: &[[f64; 4]],
    w_im: &[[f64; 4]],
    re: &[f64; 12],
    im: &[f64; 12],
) {
    for run in runs {
        let (cells, w_re, w_im, lane) = run_slices(cells, run, w_re, w_im);
        for ((cell, wr), wi) in cells.iter_mut().zip(w_re).zip(w_im) {
            let (wr, wi) = (wr[lane], wi[lane]);
            for i in 0..12 {
                cell[i] += re[i] * wr + im[i] * wi;
            }
        }
    }
}

#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "avx2")]
fn splat_avx2(
    cells: &mut [[f64; 12]],
    runs: &[Run],
    w_re: &[[f64; 4]],
    w_im: &[[f64; 4]],
    re: &[f64; 12],
    im: &[f64; 12],
) {
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
    for run in runs {
        let (cells, w_re, w_im, lane) = run_slices(cells, run, w_re, w_im);
        for ((cell, wr), wi) in cells.iter_mut().zip(w_re).zip(w_im) {
            let (a, b) = (_mm256_set1_pd(wr[lane]), _mm256_set1_pd(wi[lane]));
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
}

/// Four rows' state at their first cell, one row a lane ([`row_weights`]): the Gaussian,
/// its ratio to the next cell, the plane wave's real and imaginary parts, and the row's
/// number of cells (0 for a lane without a row).
#[derive(Clone, Copy, Debug)]
pub struct RowLanes {
    pub g: [f64; 4],
    pub r: [f64; 4],
    pub re: [f64; 4],
    pub im: [f64; 4],
    pub n: [f64; 4],
}

/// The diffraction method's patch weights for four rows at once, one per lane: at each
/// step `c` (one cell along every row) the lane's Gaussian `g` is held at 0 past its row's
/// `n` cells, added to the lanes' sums, and the cell's weight `g (re, im)` written to
/// `w_re[c]`, `w_im[c]`; then `g *= r`, `r *= alpha` and `(re, im)` turns by `turn`. Returns
/// the lanes' sums. The same products and sums in the same order on either path, no fused
/// multiply-add: the same bits (tested below).
#[inline(always)]
pub fn row_weights(
    w_re: &mut [[f64; 4]],
    w_im: &mut [[f64; 4]],
    lanes: RowLanes,
    alpha: f64,
    turn: [f64; 2],
) -> [f64; 4] {
    assert_eq!(w_re.len(), w_im.len());
    #[cfg(target_arch = "x86_64")]
    if avx2_enabled() {
        // SAFETY: `row_weights_avx2` only requires the CPU to execute AVX2 instructions,
        // which `avx2_enabled` has confirmed; its stores stay inside `w_re` and `w_im`.
        return unsafe { row_weights_avx2(w_re, w_im, lanes, alpha, turn) };
    }
    row_weights_portable(w_re, w_im, lanes, alpha, turn)
}

fn row_weights_portable(
    w_re: &mut [[f64; 4]],
    w_im: &mut [[f64; 4]],
    RowLanes {
        mut g,
        mut r,
        mut re,
        mut im,
        n,
    }: RowLanes,
    alpha: f64,
    [tr, ti]: [f64; 2],
) -> [f64; 4] {
    let mut sum = [0.0; 4];
    for (c, (wr, wi)) in w_re.iter_mut().zip(w_im.iter_mut()).enumerate() {
        let cf = c as f64;
        for l in 0..4 {
            let gm = if cf < n[l] { g[l] } else { 0.0 };
            sum[l] += gm;
            wr[l] = re[l] * gm;
            wi[l] = im[l] * gm;
            g[l] = gm * r[l];
            r[l] *= alpha;
            (re[l], im[l]) = (re[l] * tr - im[l] * ti, re[l] * ti + im[l] * tr);
        }
    }
    sum
}

#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "avx2")]
fn row_weights_avx2(
    w_re: &mut [[f64; 4]],
    w_im: &mut [[f64; 4]],
    RowLanes { g, r, re, im, n }: RowLanes,
    alpha: f64,
    [tr, ti]: [f64; 2],
) -> [f64; 4] {
    use core::arch::x86_64::{
        _CMP_LT_OQ, _mm256_add_pd, _mm256_and_pd, _mm256_cmp_pd, _mm256_loadu_pd, _mm256_mul_pd,
        _mm256_set1_pd, _mm256_setzero_pd, _mm256_storeu_pd, _mm256_sub_pd,
    };
    // SAFETY (every load and store below): the pointers are to `[f64; 4]` arrays, read or
    // written whole; `loadu`/`storeu` take any alignment.
    let load = |a: &[f64; 4]| unsafe { _mm256_loadu_pd(a.as_ptr()) };
    let (mut g, mut r, mut re, mut im, n) = (load(&g), load(&r), load(&re), load(&im), load(&n));
    let (alpha, tr, ti) = (
        _mm256_set1_pd(alpha),
        _mm256_set1_pd(tr),
        _mm256_set1_pd(ti),
    );
    let mut sum = _mm256_setzero_pd();
    for (c, (wr, wi)) in w_re.iter_mut().zip(w_im.iter_mut()).enumerate() {
        // `gm = g` where `c < n`, else +0.0 (the mask's bits and the value's).
        let gm = _mm256_and_pd(g, _mm256_cmp_pd::<_CMP_LT_OQ>(_mm256_set1_pd(c as f64), n));
        sum = _mm256_add_pd(sum, gm);
        // SAFETY: as above, whole `[f64; 4]` arrays.
        unsafe {
            _mm256_storeu_pd(wr.as_mut_ptr(), _mm256_mul_pd(re, gm));
            _mm256_storeu_pd(wi.as_mut_ptr(), _mm256_mul_pd(im, gm));
        }
        g = _mm256_mul_pd(gm, r);
        r = _mm256_mul_pd(r, alpha);
        (re, im) = (
            _mm256_sub_pd(_mm256_mul_pd(re, tr), _mm256_mul_pd(im, ti)),
            _mm256_add_pd(_mm256_mul_pd(re, ti), _mm256_mul_pd(im, tr)),
        );
    }
    let mut out = [0.0; 4];
    // SAFETY: a whole `[f64; 4]`.
    unsafe { _mm256_storeu_pd(out.as_mut_ptr(), sum) };
    out
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The splat's AVX2 path gives the portable path's bits.
    #[test]
    fn the_splat_is_the_same_bits_either_way() {
        let re: [f64; 12] = std::array::from_fn(|i| (i as f64 * 0.37).sin() * 1e-3);
        let im: [f64; 12] = std::array::from_fn(|i| (i as f64 * 1.13).cos() * 3e-4);
        let w_re: Vec<[f64; 4]> = (0..37)
            .map(|i| std::array::from_fn(|l| ((i + 37 * l) as f64 * 0.71).cos() * 0.3))
            .collect();
        let w_im: Vec<[f64; 4]> = (0..37)
            .map(|i| std::array::from_fn(|l| ((i + 37 * l) as f64 * 0.29).sin() * 0.7))
            .collect();
        let start: Vec<[f64; 12]> = (0..37)
            .map(|c| std::array::from_fn(|i| (c * 12 + i) as f64 * 1e-5 - 1e-3))
            .collect();
        // Runs of every lane, one of them overlapping another, one empty.
        let runs = [
            (0, 0, 37, 0),
            (3, 5, 20, 1),
            (10, 1, 12, 2),
            (30, 20, 7, 3),
            (4, 9, 0, 2),
        ]
        .map(|(cell, weight, len, lane)| Run {
            cell,
            weight,
            len,
            lane,
        });
        for k in 0..runs.len() - 1 {
            let mut a = start.clone();
            splat_portable(&mut a, &runs[k..], &w_re, &w_im, &re, &im);
            let mut b = start.clone();
            splat_cells(&mut b, &runs[k..], &w_re, &w_im, &re, &im);
            assert_ne!(a, start);
            assert_eq!(
                a.iter().flatten().map(|x| x.to_bits()).collect::<Vec<_>>(),
                b.iter().flatten().map(|x| x.to_bits()).collect::<Vec<_>>()
            );
        }
    }

    /// The patch weights' AVX2 path gives the portable path's bits, rows of unequal length
    /// included.
    #[test]
    fn the_row_weights_are_the_same_bits_either_way() {
        let lanes = RowLanes {
            g: [0.9, 3e-3, 0.5, 0.0],
            r: [1.3, 0.7, 0.95, 0.0],
            re: [0.6, -0.8, 1.0, 0.0],
            im: [0.8, 0.6, 0.0, 0.0],
            n: [13.0, 9.0, 17.0, 0.0],
        };
        type Kernel = fn(&mut [[f64; 4]], &mut [[f64; 4]], RowLanes, f64, [f64; 2]) -> [f64; 4];
        let run = |f: Kernel| {
            let (mut wr, mut wi) = (vec![[7.0; 4]; 17], vec![[7.0; 4]; 17]);
            let sum = f(&mut wr, &mut wi, lanes, 0.81, [0.3f64.cos(), 0.3f64.sin()]);
            let bits = |v: &[[f64; 4]]| v.iter().flatten().map(|x| x.to_bits()).collect::<Vec<_>>();
            (sum.map(f64::to_bits), bits(&wr), bits(&wi))
        };
        let a = run(row_weights_portable);
        assert_eq!(a, run(row_weights));
        // The second lane stops after 9 cells; the fourth has none.
        assert_eq!(a.1[4 * 9 + 1], 0);
        assert_ne!(a.1[4 * 8 + 1], 0);
        assert!(a.1.iter().skip(3).step_by(4).all(|&b| b == 0));
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
