/* hoc_version and hoc_status_string: every status has its own non-empty string,
 * unknown statuses get a string too, and the version is the package's. */
#include "test_common.h"

int main(int argc, char **argv) {
  const char *v = hoc_version();
  CHECK(v && *v, "empty version");
  if (argc > 1) CHECK(strcmp(v, argv[1]) == 0, "version %s, the package says %s", v, argv[1]);
  const char *s[11];
  for (HocStatus st = HOC_OK; st <= HOC_ERROR_PANIC; ++st) {
    s[st] = hoc_status_string(st);
    CHECK(s[st] && *s[st], "status %d has no string", st);
    for (HocStatus o = 0; o < st; ++o) CHECK(strcmp(s[o], s[st]) != 0, "statuses %d and %d share \"%s\"", o, st, s[st]);
    printf("%2d %s\n", st, s[st]);
  }
  const int unknown[] = {-1, 11, 42, 1 << 30};
  for (size_t i = 0; i < sizeof unknown / sizeof *unknown; ++i) {
    const char *u = hoc_status_string(unknown[i]);
    CHECK(u && *u, "unknown status %d has no string", unknown[i]);
  }
  /* The enum values the header promises. */
  CHECK(HOC_ERROR_PANIC == 10 && HOC_SPACING_EQUISPACED == 1 && HOC_ORDERING_VTK == 2 &&
            HOC_FORMULATION_NONLINEAR == 4 && HOC_MATERIAL_TRANSVERSELY_ISOTROPIC_LINEAR == 5,
        "enum values differ from SPEC");
  CHECK(sizeof(HocQuality) == 7 * sizeof(double) + 4 * sizeof(size_t), "HocQuality has padding or extra fields");
  printf("hocurve %s\n", v);
  return 0;
}
