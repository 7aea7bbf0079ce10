"""The paper's published numbers we compare against (Lin & Hsu, §2.1 Table 1, §5.2 Table 3)."""

from __future__ import annotations

# Table 1: order (log10) of the Optimal-OST search space for N = 10 agents.
TABLE1 = {10: 26, 20: 58, 30: 92, 40: 128, 50: 164, 100: 358}

# Table 3: speedup S_N relative to N = 10, rows M, columns N = 10, 20, 30, 40, 50.
TABLE3_AGENTS = (10, 20, 30, 40, 50)
TABLE3 = {
    1: (1, 0.82, 0.67, 0.61, 0.53),
    10: (1, 0.95, 0.88, 0.85, 0.82),
    20: (1, 1.01, 0.96, 0.92, 0.88),
    30: (1, 1.04, 1.02, 0.99, 0.93),
    40: (1, 1.05, 1.03, 1.04, 1.00),
    50: (1, 1.04, 1.04, 1.04, 1.00),
    100: (1, 1.08, 1.09, 1.12, 1.09),
    200: (1, 1.09, 1.14, 1.15, 1.15),
}
