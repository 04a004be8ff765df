/* The fuzz driver every fuzz target shares.
 *
 * A target is a function that runs the code under test on one input and says whether
 * the input was accepted (0) or refused (1); it aborts when an invariant breaks.
 * KG_FUZZ_TARGET turns it into LLVMFuzzerTestOneInput for libFuzzer (meson
 * -Dfuzzing=true, clang) and, built with KG_FUZZ_STANDALONE, into a main() that runs
 * it over every seed named on the command line and over deterministic mutations of
 * each (bit flips, structural bytes, the target's own words, binary specials,
 * deletions, duplications, truncations, swaps, over-long lines), then prints the
 * counts of seeds, mutations and refused inputs:
 *   fuzz_x [--mutations N] FILE...
 * Targets whose code under test takes a path write the input with kg_fuzz_write into
 * a per-run temporary directory, removed when the process exits. */
#ifndef KG_FUZZ_DRIVER_H
#define KG_FUZZ_DRIVER_H

#include <stddef.h>
#include <stdint.h>

typedef struct kg_fuzz_target {
	const char *name;                          /* "fuzz-cgats", used in messages */
	int (*run)(const uint8_t *data, size_t size); /* 0 accepted, 1 refused */
	const char *const *words;                  /* inserted by the word mutation */
	size_t nwords;
	const char *structural;                    /* bytes that matter to the format */
	size_t long_line;                          /* > 0: now and then insert a longer run */
	long mutations;                            /* per seed, unless --mutations */
} kg_fuzz_target;

/* The standalone runner (KG_FUZZ_STANDALONE builds). */
int kg_fuzz_main(const kg_fuzz_target *t, int argc, char **argv);

/* Abort with the target's name when cond is false. */
void kg_fuzz_require(const char *name, int cond, const char *what);

/* The per-run temporary directory (created on first use, removed at exit). */
const char *kg_fuzz_dir(void);

/* Write data to kg_fuzz_dir()/leaf (subdirectories created) and return its path, in a
 * buffer that stays valid until the next call. */
const char *kg_fuzz_write(const char *leaf, const uint8_t *data, size_t size);

#ifdef KG_FUZZ_STANDALONE
#define KG_FUZZ_MAIN(target)                                                            \
	int main(int argc, char **argv) { return kg_fuzz_main(&(target), argc, argv); }
#else
#define KG_FUZZ_MAIN(target)
#endif

/* Define LLVMFuzzerTestOneInput (and main() in standalone builds) for a target. */
#define KG_FUZZ_TARGET(target)                                                          \
	int LLVMFuzzerTestOneInput(const uint8_t *data, size_t size);                   \
	int LLVMFuzzerTestOneInput(const uint8_t *data, size_t size)                    \
	{                                                                               \
		(void)(target).run(data, size);                                         \
		return 0;                                                               \
	}                                                                               \
	KG_FUZZ_MAIN(target)

#endif
