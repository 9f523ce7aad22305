"""Why a gait moves a robot: the local connection, its height functions and loop estimates
(thesis Table 2.1, after Shammas). Modules: :mod:`.connection_fields` (A(r), Γ(r) and the fibre
group's bracket), :mod:`.heights` (height functions as expressions and arrays), :mod:`.stokes`
(the net displacement of a shape loop)."""
