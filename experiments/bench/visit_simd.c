/* Whether a hand-over's visits get cheaper as arrays of each field, and eight at
 * a time with AVX-512 (issue 59). The same work as experiments/bench/floor.py's
 * visit(): bring a cell k steps forward in closed form from a table of 8 values
 * a step, add its input, bound whether it might fire, store it, list it if so.
 * Two passes over the same random cells of a state of MB megabytes, kept as
 * one array per field (v, I_exc, I_inh, the step of the last update):
 *   scalar - one cell at a time, the next cells' four fields prefetched;
 *   avx512 - eight cells at a time: the fields and the table rows gathered,
 *            the results scattered, the cells that might fire compressed out.
 * (The random cells repeat so rarely that eight at a time never hold one cell
 * twice in practice; a real engine would have to make sure of it.)
 *
 *   gcc -O3 -march=native experiments/bench/visit_simd.c -o /tmp/visit_simd
 *   taskset -c 0 /tmp/visit_simd 2.8      (needs a processor with AVX-512)
 *
 * Prints CPU nanoseconds a visit for each pass, twice.
 */
#include <immintrin.h>
#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>
#include <time.h>

#define VISITS 20000000L
#define KMAX 64
#define AHEAD 48

static double cpu_s(void) {
    struct timespec t;
    clock_gettime(CLOCK_PROCESS_CPUTIME_ID, &t);
    return t.tv_sec + 1e-9 * t.tv_nsec;
}

static void *cells_of(long n) { return aligned_alloc(64, ((n * 8 + 63) / 64) * 64); }

static uint64_t next_random(uint64_t *s) { /* xorshift64 */
    *s ^= *s << 13;
    *s ^= *s >> 7;
    *s ^= *s << 17;
    return *s;
}

int main(int argc, char **argv) {
    double mb = argc > 1 ? atof(argv[1]) : 2.8;
    long n = (long)(mb * 1e6 / 32); /* 32 bytes a cell, as the engine's records */
    double *v = cells_of(n), *e = cells_of(n), *in = cells_of(n);
    int64_t *last = cells_of(n);
    for (long c = 0; c < n; c++) v[c] = -0.07, e[c] = 0.0, in[c] = 0.0, last[c] = 0;
    /* tables shaped as the engine's: decays of v, I_exc, I_inh, then v's response to each current */
    double *tab = aligned_alloc(64, (KMAX + 1) * 8 * sizeof(double));
    for (int k = 0; k <= KMAX; k++) {
        double dm = 1, de = 1, di = 1, *t = tab + 8 * k;
        for (int q = 0; q < k; q++) dm *= 0.95, de *= 0.8, di *= 0.85;
        t[0] = dm, t[1] = de, t[2] = di, t[3] = 0.1 * (de - dm), t[4] = 0.1 * (di - dm);
    }
    int64_t *idx = malloc(VISITS * 8), *now = malloc(VISITS * 8), *listed = malloc(VISITS * 8);
    double *w = malloc(VISITS * 8);
    uint64_t s = 7;
    for (long j = 0; j < VISITS; j++) {
        idx[j] = next_random(&s) % n;
        w[j] = 1e-3 * (next_random(&s) % 1000) / 1000.0;
        now[j] = j / (VISITS / 1000) + 20; /* a thousand steps */
    }
    const double v_rest = -0.07, gap = 0.01, peak = 0.2;
    for (int round = 0; round < 2; round++) {
        double t0 = cpu_s();
        long n_scalar = 0;
        for (long j = 0; j < VISITS; j++) {
            if (j + AHEAD < VISITS) {
                long h = idx[j + AHEAD];
                __builtin_prefetch(&v[h], 1), __builtin_prefetch(&e[h], 1);
                __builtin_prefetch(&in[h], 1), __builtin_prefetch(&last[h], 1);
            }
            long g = idx[j], k = now[j] - last[g];
            k = k > KMAX ? KMAX : (k < 0 ? 0 : k); /* (a second round starts from the first's steps) */
            const double *t = tab + 8 * k;
            double vv = v_rest + ((t[0] * (v[g] - v_rest) + e[g] * t[3]) - in[g] * t[4]);
            double ee = e[g] * t[1] + w[j], ii = in[g] * t[2];
            v[g] = vv, e[g] = ee, in[g] = ii, last[g] = now[j];
            double u = vv - v_rest, x = ee - ii > 0 ? ee - ii : 0;
            listed[n_scalar] = g;
            n_scalar += ((u > x ? u : x) > gap) & (((u > 0 ? u : 0) + peak * x) > gap);
        }
        double scalar = cpu_s() - t0;

        t0 = cpu_s();
        long n_simd = 0;
        const __m512d VR = _mm512_set1_pd(v_rest), GAP = _mm512_set1_pd(gap), PEAK = _mm512_set1_pd(peak);
        const __m512d ZERO = _mm512_setzero_pd();
        const __m512i TOP = _mm512_set1_epi64(KMAX), NONE = _mm512_setzero_si512();
        for (long j = 0; j + 8 <= VISITS; j += 8) {
            if (j + 8 + AHEAD < VISITS)
                for (int q = 0; q < 8; q++) {
                    long h = idx[j + AHEAD + q];
                    __builtin_prefetch(&v[h], 1), __builtin_prefetch(&e[h], 1);
                    __builtin_prefetch(&in[h], 1), __builtin_prefetch(&last[h], 1);
                }
            __m512i I = _mm512_loadu_si512(idx + j), NOW = _mm512_loadu_si512(now + j);
            __m512i L = _mm512_i64gather_epi64(I, last, 8);
            __m512i K = _mm512_max_epi64(_mm512_min_epi64(_mm512_sub_epi64(NOW, L), TOP), NONE);
            __m512i K8 = _mm512_slli_epi64(K, 3);
            __m512d V = _mm512_i64gather_pd(I, v, 8), E = _mm512_i64gather_pd(I, e, 8);
            __m512d IN = _mm512_i64gather_pd(I, in, 8);
            __m512d T0 = _mm512_i64gather_pd(K8, tab, 8), T1 = _mm512_i64gather_pd(K8, tab + 1, 8);
            __m512d T2 = _mm512_i64gather_pd(K8, tab + 2, 8), T3 = _mm512_i64gather_pd(K8, tab + 3, 8);
            __m512d T4 = _mm512_i64gather_pd(K8, tab + 4, 8);
            __m512d VV = _mm512_add_pd(
                VR, _mm512_sub_pd(_mm512_add_pd(_mm512_mul_pd(T0, _mm512_sub_pd(V, VR)), _mm512_mul_pd(E, T3)),
                                  _mm512_mul_pd(IN, T4)));
            __m512d EE = _mm512_add_pd(_mm512_mul_pd(E, T1), _mm512_loadu_pd(w + j));
            __m512d II = _mm512_mul_pd(IN, T2);
            _mm512_i64scatter_pd(v, I, VV, 8), _mm512_i64scatter_pd(e, I, EE, 8);
            _mm512_i64scatter_pd(in, I, II, 8), _mm512_i64scatter_epi64(last, I, NOW, 8);
            __m512d U = _mm512_sub_pd(VV, VR), X = _mm512_max_pd(_mm512_sub_pd(EE, II), ZERO);
            __mmask8 might = _mm512_cmp_pd_mask(_mm512_max_pd(U, X), GAP, _CMP_GT_OQ) &
                             _mm512_cmp_pd_mask(_mm512_fmadd_pd(PEAK, X, _mm512_max_pd(U, ZERO)), GAP, _CMP_GT_OQ);
            _mm512_mask_compressstoreu_epi64(listed + n_simd, might, I);
            n_simd += __builtin_popcount(might);
        }
        double simd = cpu_s() - t0;
        printf("%.1f MB, round %d: scalar %.2f ns a visit, avx512 %.2f ns a visit (%ld and %ld listed)\n", mb,
               round + 1, 1e9 * scalar / VISITS, 1e9 * simd / VISITS, n_scalar, n_simd);
    }
    return 0;
}
