/*
 * QEMU TCG plugin: counts the guest instructions executed between two marker instructions
 * the firmware's `bench` build puts around each identifier step (firmware/src/bench.rs):
 * `mov r9, r9` (Thumb 0x46C9) before, `mov r10, r10` (0x46D2) after. Prints min / mean / max
 * per interval at exit, and the number of VDIV.F32 among them (14-cycle instructions on the
 * Cortex-M4F, for the cycle estimate).
 *
 *   qemu-system-arm ... -plugin ./libinsncount.so -d plugin
 *
 * The first interval is the calibration call (begin immediately followed by end): its count
 * is the markers' own overhead, subtracted from every later interval.
 *
 * Debian ships QEMU without its plugin header, so the few declarations used are written out
 * here from the documented plugin API (include/qemu/qemu-plugin.h, API version 1 in QEMU 7.2).
 */
#include <inttypes.h>
#include <stdbool.h>
#include <stddef.h>
#include <stdint.h>
#include <stdio.h>

typedef uint64_t qemu_plugin_id_t;
typedef struct qemu_info_t qemu_info_t; /* not inspected */
struct qemu_plugin_tb;
struct qemu_plugin_insn;
enum qemu_plugin_cb_flags { QEMU_PLUGIN_CB_NO_REGS, QEMU_PLUGIN_CB_R_REGS, QEMU_PLUGIN_CB_RW_REGS };
enum qemu_plugin_op { QEMU_PLUGIN_INLINE_ADD_U64 };
typedef void (*qemu_plugin_vcpu_tb_trans_cb_t)(qemu_plugin_id_t id, struct qemu_plugin_tb *tb);
typedef void (*qemu_plugin_vcpu_udata_cb_t)(unsigned int vcpu_index, void *userdata);
typedef void (*qemu_plugin_udata_cb_t)(qemu_plugin_id_t id, void *userdata);

extern void qemu_plugin_register_vcpu_tb_trans_cb(qemu_plugin_id_t id, qemu_plugin_vcpu_tb_trans_cb_t cb);
extern size_t qemu_plugin_tb_n_insns(const struct qemu_plugin_tb *tb);
extern struct qemu_plugin_insn *qemu_plugin_tb_get_insn(const struct qemu_plugin_tb *tb, size_t idx);
extern const void *qemu_plugin_insn_data(const struct qemu_plugin_insn *insn);
extern size_t qemu_plugin_insn_size(const struct qemu_plugin_insn *insn);
extern void qemu_plugin_register_vcpu_insn_exec_cb(struct qemu_plugin_insn *insn, qemu_plugin_vcpu_udata_cb_t cb,
                                                   enum qemu_plugin_cb_flags flags, void *userdata);
extern void qemu_plugin_register_vcpu_insn_exec_inline(struct qemu_plugin_insn *insn, enum qemu_plugin_op op,
                                                       void *ptr, uint64_t imm);
extern void qemu_plugin_register_atexit_cb(qemu_plugin_id_t id, qemu_plugin_udata_cb_t cb, void *userdata);
extern void qemu_plugin_outs(const char *string);

__attribute__((visibility("default"))) int qemu_plugin_version = 1;

static uint64_t insns, vdivs;        /* running totals, incremented inline */
static uint64_t start_insns, start_vdivs;
static bool inside;
static uint64_t n, sum, min_i = UINT64_MAX, max_i, overhead, sum_vdiv, max_vdiv;
static bool calibrated;

static void on_begin(unsigned int vcpu, void *u) {
    (void)vcpu; (void)u;
    start_insns = insns;
    start_vdivs = vdivs;
    inside = true;
}

static void on_end(unsigned int vcpu, void *u) {
    (void)vcpu; (void)u;
    if (!inside) return;
    inside = false;
    uint64_t d = insns - start_insns, v = vdivs - start_vdivs;
    if (!calibrated) { overhead = d; calibrated = true; return; }
    d = d > overhead ? d - overhead : 0;
    n++; sum += d; sum_vdiv += v;
    if (d < min_i) min_i = d;
    if (d > max_i) max_i = d;
    if (v > max_vdiv) max_vdiv = v;
}

/* VDIV.F32 (T1/A1): 1110 1110 1D00 Vn | Vd 101 0 N0M0 Vm. */
static bool is_vdiv_f32(const struct qemu_plugin_insn *insn) {
    if (qemu_plugin_insn_size(insn) != 4) return false;
    const uint8_t *b = qemu_plugin_insn_data(insn);
    uint16_t hw1 = (uint16_t)(b[0] | (b[1] << 8)), hw2 = (uint16_t)(b[2] | (b[3] << 8));
    return (hw1 & 0xFFB0) == 0xEE80 && (hw2 & 0x0F50) == 0x0A00;
}

/* 1: `mov r9, r9`, 2: `mov r10, r10`, 0: anything else. */
static int marker(const struct qemu_plugin_insn *insn) {
    if (qemu_plugin_insn_size(insn) != 2) return 0;
    const uint8_t *b = qemu_plugin_insn_data(insn);
    uint16_t hw = (uint16_t)(b[0] | (b[1] << 8));
    return hw == 0x46C9 ? 1 : hw == 0x46D2 ? 2 : 0;
}

static void on_tb(qemu_plugin_id_t id, struct qemu_plugin_tb *tb) {
    (void)id;
    size_t k = qemu_plugin_tb_n_insns(tb);
    for (size_t i = 0; i < k; i++) {
        struct qemu_plugin_insn *insn = qemu_plugin_tb_get_insn(tb, i);
        int m = marker(insn);
        /* Marker callbacks first, so the begin marker counts inside, the end marker not. */
        if (m == 1) qemu_plugin_register_vcpu_insn_exec_cb(insn, on_begin, QEMU_PLUGIN_CB_NO_REGS, NULL);
        if (m == 2) qemu_plugin_register_vcpu_insn_exec_cb(insn, on_end, QEMU_PLUGIN_CB_NO_REGS, NULL);
        qemu_plugin_register_vcpu_insn_exec_inline(insn, QEMU_PLUGIN_INLINE_ADD_U64, &insns, 1);
        if (is_vdiv_f32(insn)) qemu_plugin_register_vcpu_insn_exec_inline(insn, QEMU_PLUGIN_INLINE_ADD_U64, &vdivs, 1);
    }
}

static void on_exit_cb(qemu_plugin_id_t id, void *u) {
    (void)id; (void)u;
    char buf[512];
    if (n == 0) {
        snprintf(buf, sizeof buf, "insn-count: no complete interval (is this a `bench` build?)\n");
    } else {
        snprintf(buf, sizeof buf,
                 "insn-count: intervals=%" PRIu64 " min=%" PRIu64 " mean=%.1f max=%" PRIu64
                 " overhead=%" PRIu64 " vdiv_mean=%.2f vdiv_max=%" PRIu64 " total_insns=%" PRIu64 "\n",
                 n, min_i, (double)sum / (double)n, max_i, overhead, (double)sum_vdiv / (double)n, max_vdiv, insns);
    }
    qemu_plugin_outs(buf);
}

__attribute__((visibility("default"))) int qemu_plugin_install(qemu_plugin_id_t id, const qemu_info_t *info,
                                                               int argc, char **argv) {
    (void)info; (void)argc; (void)argv;
    qemu_plugin_register_vcpu_tb_trans_cb(id, on_tb);
    qemu_plugin_register_atexit_cb(id, on_exit_cb, NULL);
    return 0;
}
