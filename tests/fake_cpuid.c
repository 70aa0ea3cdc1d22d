/* LD_PRELOAD shim for tests/test_pocl_avx512.py: makes the process's CPUID instruction fault
 * (Linux arch_prctl ARCH_SET_CPUID: CPUs with the "cpuid_fault" flag) and answers it with another
 * CPU's identity, so LLVM's getHostCPUName() inside pip's PoCL names that CPU while the code still
 * runs on this one. FAKECPU=zen4: AMD family 19h model 11h (EPYC Genoa; LLVM < 16 names every
 * family-19h CPU "znver3", a target without AVX-512) with this CPU's own feature leaves. Any other
 * value, or none: no change. Exits with status 3 at load when CPUID faulting is unavailable. */
#define _GNU_SOURCE
#include <asm/prctl.h>
#include <cpuid.h>
#include <signal.h>
#include <stdlib.h>
#include <string.h>
#include <sys/syscall.h>
#include <ucontext.h>
#include <unistd.h>

static void real_cpuid(unsigned leaf, unsigned sub, unsigned r[4])
{
    syscall(SYS_arch_prctl, ARCH_SET_CPUID, 1);
    __cpuid_count(leaf, sub, r[0], r[1], r[2], r[3]);
    syscall(SYS_arch_prctl, ARCH_SET_CPUID, 0);
}

static void on_segv(int sig, siginfo_t *si, void *ctx)
{
    greg_t *g = ((ucontext_t *)ctx)->uc_mcontext.gregs;
    unsigned char *ip = (unsigned char *)g[REG_RIP];
    (void)sig; (void)si;
    if (ip[0] != 0x0f || ip[1] != 0xa2) {       /* a real fault: die of it as usual */
        signal(SIGSEGV, SIG_DFL);
        return;
    }
    unsigned leaf = (unsigned)g[REG_RAX], sub = (unsigned)g[REG_RCX], r[4];
    real_cpuid(leaf, sub, r);
    if (leaf == 0) { r[1] = 0x68747541; r[3] = 0x69746e65; r[2] = 0x444d4163; }   /* "AuthenticAMD" */
    if (leaf == 1) r[0] = 0x00A10F11;                                              /* family 19h, model 11h */
    g[REG_RAX] = r[0]; g[REG_RBX] = r[1]; g[REG_RCX] = r[2]; g[REG_RDX] = r[3];
    g[REG_RIP] += 2;                                                               /* past the cpuid */
}

__attribute__((constructor)) static void init(void)
{
    const char *mode = getenv("FAKECPU");
    if (!mode || strcmp(mode, "zen4") != 0)
        return;
    struct sigaction sa;
    memset(&sa, 0, sizeof sa);
    sa.sa_sigaction = on_segv;
    sa.sa_flags = SA_SIGINFO | SA_NODEFER;
    sigaction(SIGSEGV, &sa, NULL);
    if (syscall(SYS_arch_prctl, ARCH_SET_CPUID, 0) != 0)
        _exit(3);
}
