"""From a texplorer database to a plot: features, feature quality, cross-validation, one figure.

Usage: python analysis.py [DATABASE] [OUT.png]   (defaults: texplorer-data, analysis.png)
"""

import sys

import matplotlib

matplotlib.use("Agg")  # draw to a file, no window
import matplotlib.pyplot as plt
import numpy as np

import scanner
from features.selection import feature_quality
from scanner.workflows.database import extract_database
from taxonomy.learning.evaluation import evaluate

root = sys.argv[1] if len(sys.argv) > 1 else "texplorer-data"
out = sys.argv[2] if len(sys.argv) > 2 else "analysis.png"

# 1. The database's feature space: rows from the feature cache, the others extracted (and cached).
db = scanner.Database(root)
space = extract_database(db, workers=1, progress=False)
print(f"{len(space.X)} scans x {len(space.columns)} features, {len(set(space.y('fine')))} materials")

# 2. Feature quality (Strese et al. 2020, eq. 31) of every column at the fine level, best first.
fq = feature_quality(space.X, space.y("fine"))
order = np.argsort(-fq, kind="stable")
for i in order[:5]:
    print(f"FQ {fq[i]:5.1f} %  {space.columns[i]}")

# 3. Random forest on the 10 features FQ + Spearman selects, cross-validated with folds by sample.
for level in ("coarse", "fine"):
    result = evaluate(space, classifier="rf", level=level, n_features=10, folds=2)
    print(f"{level:6s} accuracy {100 * result.accuracy_mean:5.1f} % +- {100 * result.accuracy_std:4.1f}")

# 4. The best feature per major class, as the report's box plots (the paper's Fig. 14).
best = space.columns[order[0]]
column = space.X[:, order[0]]
classes = sorted(set(space.y("coarse")))
groups = [column[np.asarray(space.y("coarse")) == c] for c in classes]
fig, ax = plt.subplots(figsize=(6, 3.5))
ax.boxplot(groups)
ax.set_xticks(range(1, len(classes) + 1), classes)
ax.set_xlabel("major class")
ax.set_ylabel(best)
fig.tight_layout()
fig.savefig(out, dpi=100)
print(f"wrote {out}")
