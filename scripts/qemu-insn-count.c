/* A qemu-user TCG plugin (plugin API version 1, as in Debian's qemu 7.2) that counts the guest
 * instructions a program executes, in total and per translation block: at exit it writes
 * "vaddr insns execs" lines and "total N" to the file named by $TBCOUNT_OUT. Instruction counts,
 * not time: how the aarch64 (NEON) build was measured on an x86 machine (scripts/aarch64-count.sh,
 * docs/perf-notes.md). Count one guest thread (--threads 1): the counters are not atomic.
 * Build: gcc -shared -fPIC -O2 -o qemu-insn-count.so qemu-insn-count.c
 *        -Wl,--unresolved-symbols=ignore-all   (the API symbols come from qemu at load time) */
#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>
#include <stdbool.h>
#include <stddef.h>
typedef uint64_t qemu_plugin_id_t;
struct qemu_plugin_tb;
typedef struct qemu_info_t qemu_info_t;
enum qemu_plugin_op { QEMU_PLUGIN_INLINE_ADD_U64 };
typedef void (*tb_trans_cb)(qemu_plugin_id_t, struct qemu_plugin_tb *);
typedef void (*udata_cb)(qemu_plugin_id_t, void *);
extern void qemu_plugin_register_vcpu_tb_trans_cb(qemu_plugin_id_t, tb_trans_cb);
extern size_t qemu_plugin_tb_n_insns(const struct qemu_plugin_tb *);
extern uint64_t qemu_plugin_tb_vaddr(const struct qemu_plugin_tb *);
extern void qemu_plugin_register_vcpu_tb_exec_inline(struct qemu_plugin_tb *, enum qemu_plugin_op, void *, uint64_t);
extern void qemu_plugin_register_atexit_cb(qemu_plugin_id_t, udata_cb, void *);
__attribute__((visibility("default"))) int qemu_plugin_version = 1;
struct rec { uint64_t vaddr; uint64_t n; uint64_t execs; struct rec *next; };
static struct rec *head;
static void trans(qemu_plugin_id_t id, struct qemu_plugin_tb *tb) {
  struct rec *r = calloc(1, sizeof *r);
  r->vaddr = qemu_plugin_tb_vaddr(tb); r->n = qemu_plugin_tb_n_insns(tb);
  r->next = head; head = r;   /* translation is serialised by qemu's tb lock */
  qemu_plugin_register_vcpu_tb_exec_inline(tb, QEMU_PLUGIN_INLINE_ADD_U64, &r->execs, 1);
}
static void done(qemu_plugin_id_t id, void *p) {
  const char *path = getenv("TBCOUNT_OUT"); FILE *f = fopen(path ? path : "/tmp/tbcount.txt", "w");
  uint64_t total = 0;
  for (struct rec *r = head; r; r = r->next) { if (r->execs) fprintf(f, "%lx %lu %lu\n", r->vaddr, r->n, r->execs); total += r->n * r->execs; }
  fprintf(f, "total %lu\n", total); fclose(f);
}
__attribute__((visibility("default"))) int qemu_plugin_install(qemu_plugin_id_t id, const qemu_info_t *info, int argc, char **argv) {
  qemu_plugin_register_vcpu_tb_trans_cb(id, trans);
  qemu_plugin_register_atexit_cb(id, done, NULL);
  return 0;
}
