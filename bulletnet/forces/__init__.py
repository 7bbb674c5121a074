"""Force kernels, written once and used by every engine (fast, bullet, reference)."""
