"""The paper's evaluation reproduced: Table 1, Fig. 6, Figs. 4-5, Fig. S3 and its event conversion
(D'Angelo et al. 2025, against the human labels of BSDS). See experiments/README.md."""
