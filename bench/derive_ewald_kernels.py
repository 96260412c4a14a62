"""Derivation of the Ewald (Hasimoto) splitting of the RPY and Stokeslet kernels used by
particle/src/ewald.rs. Run: python3 bench/derive_ewald_kernels.py (needs sympy).

Fourier part (smooth, free space) of a kernel with Fourier transform (I - kk/k^2) h(k)/k^2 and
Hasimoto screening phi(k) = (1 + k^2/(4 xi^2)) exp(-k^2/(4 xi^2)):
    M_F = -(nabla^2 I - nabla nabla) s,   s = F^-1[phi(k) (1 - a^2 k^2/6)^2 / k^4]  (mu = 1)
For radial s: M_F = A I + B rr/r^2 with A = -(s'' + s'/r), B = -(s'/r - s'').
s' comes from w = nabla^2 s0 = F^-1[-phi/k^2] (closed form below) by
s0' = r^-2 int_0^r rho^2 w, and the RPY factor (1 + a^2 nabla^2/6)^2 adds (a^2/3) w' +
(a^4/36) (nabla^2 w)'. The real-space part is M_far - M_F.
"""
import sympy as sp

r, xi, a, rho = sp.symbols("r xi a rho", positive=True)
w = -(sp.erf(xi * r) + xi * r / sp.sqrt(sp.pi) * sp.exp(-xi**2 * r**2)) / (4 * sp.pi * r)
lap = lambda f: sp.diff(f, r, 2) + 2 * sp.diff(f, r) / r
s0p = sp.integrate((rho**2 * w.subs(r, rho)), (rho, 0, r)) / r**2
s0p = sp.simplify(s0p)
sp_rpy = s0p + a**2 / 3 * sp.diff(w, r) + a**4 / 36 * sp.diff(lap(w), r)
spp = sp.diff(sp_rpy, r)
A_F = sp.simplify(-(spp + sp_rpy / r))
B_F = sp.simplify(-(sp_rpy / r - spp))
A_far = (1 / r + 2 * a**2 / (3 * r**3)) / (8 * sp.pi)
B_far = (1 / r - 2 * a**2 / r**3) / (8 * sp.pi)
A_R = sp.simplify(sp.expand(A_far - A_F).rewrite(sp.erfc))
B_R = sp.simplify(sp.expand(B_far - B_F).rewrite(sp.erfc))
print("A_R =", A_R)
print("B_R =", B_R)
A0 = sp.limit(A_F, r, 0)
B0 = sp.limit(B_F, r, 0)
print("A_F(0) =", sp.simplify(A0), " B_F(0) =", B0)
# Stokeslet (a = 0) real part and derivatives for the stresslet model: G_R = A I + C x x.
A_S = sp.simplify(A_R.subs(a, 0))
C_S = sp.simplify(B_R.subs(a, 0) / r**2)
for name, f in [("A", A_S), ("C", C_S)]:
    for d in range(3):
        print(f"{name}^({d}) =", sp.simplify(sp.diff(f, r, d)))
# Taylor check of the free Fourier part near 0 (for small-r evaluation).
print("A_F series:", sp.series(A_F, r, 0, 3))
print("B_F series:", sp.series(B_F, r, 0, 3))
# Series of the smooth Fourier part for the table's first nodes: A_F and B_F / r^2 to r^6.
print("A_F series6:", sp.collect(sp.expand(sp.series(A_F, r, 0, 8).removeO()), r))
print("B_F/r^2 series6:", sp.collect(sp.expand(sp.series(B_F / r**2, r, 0, 8).removeO()), r))
