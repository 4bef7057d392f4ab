"""The installed Python package, imported from the prefix (run by tests/consumer/run.cmake)."""
import sys

import incise

assert incise.__file__.startswith(sys.argv[1]), f"{incise.__file__} is not under {sys.argv[1]}"
mesh = incise.generate_box(1.0, 2)
assert incise.quality(mesh)["counts"]["tets"] == 48
print("python: installed module ok:", incise.__file__)
