/*
 * QEMU TCG plugin: counts the guest instructions executed between the marker instructions
 * the firmware's `bench` build puts around each step of the paper's identifier (`mov r9, r9`,
 * Thumb 0x46C9, before; `mov r10, r10`, 0x46D2, after), each step of the refined identifier
 * (`mov r11, r11` / `mov r12, r12`) and each sample-loop iteration (`mov r8, r8` /
 * `mov lr, lr`); see firmware/src/bench.rs. Prints min / mean / max per interval of each pair
 * at exit (and median, 99th and 99.9th percentiles, and which interval, counted from 1, was the
 * longest), and the number of VDIV.F32 among them (14-cycle instructions on the Cortex-M4F,
 * for the cycle estimate).
 *
 *   qemu-system-arm ... -plugin ./libinsncount.so -d plugin
 *
 * The first interval of each pair is the calibration call (begin immediately followed by
 * end): its count is the markers' own overhead, subtracted from every later interval.
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

/* One channel per marker pair (firmware/src/bench.rs); channels may nest (the loop's holds
 * both steps), each keeps its own start and statistics. */
#define NCH 3
static const char *const names[NCH] = {"paper", "refined", "loop"};
static const uint16_t begin_hw[NCH] = {0x46C9 /* mov r9,r9 */, 0x46DB /* mov r11,r11 */, 0x46C0 /* mov r8,r8 */};
static const uint16_t end_hw[NCH] = {0x46D2 /* mov r10,r10 */, 0x46E4 /* mov r12,r12 */, 0x46F6 /* mov lr,lr */};
#define HIST 65536 /* intervals longer than this count in the last bin (max is exact) */
struct channel {
    uint64_t start_insns, start_vdivs;
    bool inside, calibrated;
    uint64_t n, sum, min_i, max_i, max_at, overhead, sum_vdiv, max_vdiv;
    uint32_t hist[HIST];
};
static struct channel ch[NCH];

static void on_begin(unsigned int vcpu, void *u) {
    (void)vcpu;
    struct channel *c = u;
    c->start_insns = insns;
    c->start_vdivs = vdivs;
    c->inside = true;
}

static void on_end(unsigned int vcpu, void *u) {
    (void)vcpu;
    struct channel *c = u;
    if (!c->inside) return;
    c->inside = false;
    uint64_t d = insns - c->start_insns, v = vdivs - c->start_vdivs;
    if (!c->calibrated) { c->overhead = d; c->calibrated = true; return; }
    d = d > c->overhead ? d - c->overhead : 0;
    c->n++; c->sum += d; c->sum_vdiv += v;
    if (d < c->min_i) c->min_i = d;
    if (d > c->max_i) { c->max_i = d; c->max_at = c->n; }
    if (v > c->max_vdiv) c->max_vdiv = v;
    c->hist[d < HIST ? d : HIST - 1]++;
}

/* The smallest count with at least a fraction q of the intervals at or below it. */
static uint64_t quantile(const struct channel *c, double q) {
    uint64_t need = (uint64_t)(q * (double)c->n + 0.999999), seen = 0;
    for (uint64_t d = 0; d < HIST; d++) {
        seen += c->hist[d];
        if (seen >= need) return d;
    }
    return c->max_i;
}

/* VDIV.F32 (T1/A1): 1110 1110 1D00 Vn | Vd 101 0 N0M0 Vm. */
static bool is_vdiv_f32(const struct qemu_plugin_insn *insn) {
    if (qemu_plugin_insn_size(insn) != 4) return false;
    const uint8_t *b = qemu_plugin_insn_data(insn);
    uint16_t hw1 = (uint16_t)(b[0] | (b[1] << 8)), hw2 = (uint16_t)(b[2] | (b[3] << 8));
    return (hw1 & 0xFFB0) == 0xEE80 && (hw2 & 0x0F50) == 0x0A00;
}

/* The 16-bit encoding of a 2-byte instruction, 0 for a 4-byte one. */
static uint16_t halfword(const struct qemu_plugin_insn *insn) {
    if (qemu_plugin_insn_size(insn) != 2) return 0;
    const uint8_t *b = qemu_plugin_insn_data(insn);
    return (uint16_t)(b[0] | (b[1] << 8));
}

static void on_tb(qemu_plugin_id_t id, struct qemu_plugin_tb *tb) {
    (void)id;
    size_t k = qemu_plugin_tb_n_insns(tb);
    for (size_t i = 0; i < k; i++) {
        struct qemu_plugin_insn *insn = qemu_plugin_tb_get_insn(tb, i);
        uint16_t hw = halfword(insn);
        /* Marker callbacks first, so the begin marker counts inside, the end marker not. */
        for (int c = 0; c < NCH; c++) {
            if (hw == begin_hw[c]) qemu_plugin_register_vcpu_insn_exec_cb(insn, on_begin, QEMU_PLUGIN_CB_NO_REGS, &ch[c]);
            if (hw == end_hw[c]) qemu_plugin_register_vcpu_insn_exec_cb(insn, on_end, QEMU_PLUGIN_CB_NO_REGS, &ch[c]);
        }
        qemu_plugin_register_vcpu_insn_exec_inline(insn, QEMU_PLUGIN_INLINE_ADD_U64, &insns, 1);
        if (is_vdiv_f32(insn)) qemu_plugin_register_vcpu_insn_exec_inline(insn, QEMU_PLUGIN_INLINE_ADD_U64, &vdivs, 1);
    }
}

static void on_exit_cb(qemu_plugin_id_t id, void *u) {
    (void)id; (void)u;
    char buf[512];
    for (int i = 0; i < NCH; i++) {
        const struct channel *c = &ch[i];
        if (c->n == 0) {
            snprintf(buf, sizeof buf, "insn-count %s: no complete interval (is this a `bench` build?)\n", names[i]);
        } else {
            snprintf(buf, sizeof buf,
                     "insn-count %s: intervals=%" PRIu64 " min=%" PRIu64 " median=%" PRIu64
                     " mean=%.1f p99=%" PRIu64 " p99.9=%" PRIu64 " max=%" PRIu64 " max_at=%" PRIu64 " overhead=%" PRIu64
                     " vdiv_mean=%.2f vdiv_max=%" PRIu64 "\n",
                     names[i], c->n, c->min_i, quantile(c, 0.5), (double)c->sum / (double)c->n,
                     quantile(c, 0.99), quantile(c, 0.999), c->max_i, c->max_at, c->overhead,
                     (double)c->sum_vdiv / (double)c->n, c->max_vdiv);
        }
        qemu_plugin_outs(buf);
    }
    snprintf(buf, sizeof buf, "insn-count total: total_insns=%" PRIu64 "\n", insns);
    qemu_plugin_outs(buf);
}

__attribute__((visibility("default"))) int qemu_plugin_install(qemu_plugin_id_t id, const qemu_info_t *info,
                                                               int argc, char **argv) {
    (void)info; (void)argc; (void)argv;
    qemu_plugin_register_vcpu_tb_trans_cb(id, on_tb);
    for (int c = 0; c < NCH; c++) ch[c].min_i = UINT64_MAX;
    qemu_plugin_register_atexit_cb(id, on_exit_cb, NULL);
    return 0;
}
