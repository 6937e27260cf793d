// The machine's own limits, for reading the kernels' profiles against (docs/perf-notes.md,
// "Stage by stage against this machine's limits"): the core clock, how many vector
// instructions of each kind issue per cycle, and the bandwidth of streaming over a buffer the
// size of the aggregation's sum volume. x86-64 with AVX-512 (BW, VBMI, VPOPCNTDQ) only.
//
//   gcc -O2 -mavx512f -mavx512bw scripts/machine-limits.c -o /tmp/machine-limits && /tmp/machine-limits
//
// Rates are per cycle of the measured clock (eight independent instructions per loop iteration,
// loop overhead included); streaming is the best of five passes.
#include <immintrin.h>
#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <time.h>

static double now(void) {
  struct timespec t;
  clock_gettime(CLOCK_MONOTONIC, &t);
  return t.tv_sec + t.tv_nsec * 1e-9;
}

static uint8_t buf[4096] __attribute__((aligned(64)));

// One dependent scalar add per cycle: the clock the core runs at.
static double clock_ghz(void) {
  long n = 400000000, x = 0;
  double t0 = now();
  __asm__ volatile("mov %1, %%rcx\n1:\n"
                   "add $1, %0\n add $1, %0\n add $1, %0\n add $1, %0\n"
                   "add $1, %0\n add $1, %0\n add $1, %0\n add $1, %0\n"
                   "sub $8, %%rcx\n jnz 1b\n"
                   : "+r"(x) : "r"(n) : "rcx");
  return n / (now() - t0) / 1e9;
}

#define X8(a) a a a a a a a a
// Eight independent instructions per iteration (registers 0-7 written, 8-9 read).
#define RATE(name, body)                                                                          \
  {                                                                                               \
    long n = 50000000;                                                                            \
    double t0 = now();                                                                            \
    __asm__ volatile("mov %0, %%rcx\n1:\n" body "dec %%rcx\n jnz 1b\n" ::"r"(n), "r"(buf)           \
                     : "rcx", "memory", "xmm0", "xmm1", "xmm2", "xmm3", "xmm4", "xmm5", "xmm6",    \
                       "xmm7", "xmm8", "xmm9");                                                   \
    printf("%-28s %.2f per cycle\n", name, 8.0 * n / ((now() - t0) * ghz * 1e9));                 \
  }
#define OP8(op, r)                                                                                \
  op " %%" r "8, %%" r "9, %%" r "0\n " op " %%" r "8, %%" r "9, %%" r "1\n " op " %%" r "8, %%" r \
     "9, %%" r "2\n " op " %%" r "8, %%" r "9, %%" r "3\n " op " %%" r "8, %%" r "9, %%" r         \
     "4\n " op " %%" r "8, %%" r "9, %%" r "5\n " op " %%" r "8, %%" r "9, %%" r "6\n " op         \
     " %%" r "8, %%" r "9, %%" r "7\n"

static void stream(size_t mib) {
  size_t n = mib << 20;
  char *a = aligned_alloc(64, n);
  memset(a, 1, n);
  __m512i one = _mm512_set1_epi16(1);
  double best_w = 0, best_rmw = 0;
  for (int r = 0; r < 5; r++) {
    double t0 = now();
    for (size_t i = 0; i < n; i += 64) _mm512_store_si512(a + i, one);
    double w = n / (now() - t0) / 1e9;
    t0 = now();
    for (size_t i = 0; i < n; i += 64)
      _mm512_store_si512(a + i, _mm512_add_epi16(_mm512_load_si512(a + i), one));
    double rmw = 2.0 * n / (now() - t0) / 1e9;
    best_w = w > best_w ? w : best_w;
    best_rmw = rmw > best_rmw ? rmw : best_rmw;
  }
  printf("%4zu MiB buffer, one thread: write %.0f GB/s, read-modify-write %.0f GB/s (bytes moved)\n",
         mib, best_w, best_rmw);
  free(a);
}

int main(void) {
  double ghz = clock_ghz();
  printf("clock                        %.2f GHz\n", ghz);
  RATE("vpminub zmm", OP8("vpminub", "zmm"))
  RATE("vpminub xmm", OP8("vpminub", "xmm"))
  RATE("vpaddw zmm", OP8("vpaddw", "zmm"))
  RATE("vpermt2b zmm", OP8("vpermt2b", "zmm"))
  RATE("vpermb zmm", OP8("vpermb", "zmm"))
  RATE("vpopcntq zmm", X8("vpopcntq %%zmm8, %%zmm0\n"))
  RATE("zmm load (L1)", "vmovdqu64 (%1), %%zmm0\n vmovdqu64 64(%1), %%zmm1\n vmovdqu64 128(%1), %%zmm2\n"
       " vmovdqu64 192(%1), %%zmm3\n vmovdqu64 256(%1), %%zmm4\n vmovdqu64 320(%1), %%zmm5\n"
       " vmovdqu64 384(%1), %%zmm6\n vmovdqu64 448(%1), %%zmm7\n")
  RATE("zmm store (L1)", "vmovdqu64 %%zmm0, (%1)\n vmovdqu64 %%zmm1, 64(%1)\n vmovdqu64 %%zmm2, 128(%1)\n"
       " vmovdqu64 %%zmm3, 192(%1)\n vmovdqu64 %%zmm4, 256(%1)\n vmovdqu64 %%zmm5, 320(%1)\n"
       " vmovdqu64 %%zmm6, 384(%1)\n vmovdqu64 %%zmm7, 448(%1)\n")
  stream(16);
  stream(256);
  return 0;
}
