/* hoc_version and hoc_status_string: every status has its own non-empty string,
 * unknown statuses get a string too, and the version (the string and the
 * HOCURVE_VERSION_* macros of the header) is the package's. */
#include "test_common.h"

int main(int argc, char **argv) {
  const char *v = hoc_version();
  CHECK(v && *v, "empty version");
  if (argc > 1) CHECK(strcmp(v, argv[1]) == 0, "version %s, the package says %s", v, argv[1]);
  char macros[64];
  snprintf(macros, sizeof macros, "%d.%d.%d", HOCURVE_VERSION_MAJOR, HOCURVE_VERSION_MINOR, HOCURVE_VERSION_PATCH);
  CHECK(strcmp(v, macros) == 0, "the header says %s, the library %s", macros, v);
  const char *s[12];
  for (HocStatus st = HOC_OK; st <= HOC_ERROR_BUSY; ++st) {
    s[st] = hoc_status_string(st);
    CHECK(s[st] && *s[st], "status %d has no string", st);
    for (HocStatus o = 0; o < st; ++o) CHECK(strcmp(s[o], s[st]) != 0, "statuses %d and %d share \"%s\"", o, st, s[st]);
    printf("%2d %s\n", st, s[st]);
  }
  const int unknown[] = {-1, 12, 42, 1 << 30};
  for (size_t i = 0; i < sizeof unknown / sizeof *unknown; ++i) {
    const char *u = hoc_status_string(unknown[i]);
    CHECK(u && *u, "unknown status %d has no string", unknown[i]);
  }
  /* The enum values the header promises. */
  CHECK(HOC_ERROR_PANIC == 10 && HOC_ERROR_BUSY == 11 && HOC_SPACING_EQUISPACED == 1 && HOC_ORDERING_VTK == 2 &&
            HOC_FORMULATION_NONLINEAR == 4 && HOC_MATERIAL_TRANSVERSELY_ISOTROPIC_LINEAR == 5,
        "enum values differ from the documented ones");
  CHECK(HOC_STAGE_ELEVATE == 0 && HOC_STAGE_OPTIMIZE == 4 && HOC_DEFAULT_INCREMENTS == 10, "stage or default values");
  CHECK(sizeof(HocQuality) == 8 * sizeof(double) + 4 * sizeof(size_t), "HocQuality has padding or extra fields");
  printf("hocurve %s\n", v);
  return 0;
}
