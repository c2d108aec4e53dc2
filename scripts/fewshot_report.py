"""Table, JSON and figure of scripts/fewshot_study.sh: OUT FREEZES RATES FAMILIES SHOTS."""
import json
import sys

import matplotlib
matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402

out, freezes, rates, families, shots = sys.argv[1], *(a.split() for a in sys.argv[2:6])
load = lambda name: json.load(open(f"{out}/eval_{name}.json"))  # noqa: E731
chosen = open(f"{out}/chosen.txt").read().strip()

lines = ["Selection on the validation family `loose`, n = 50 target strikes (MED cm):", "",
         "| freeze | " + " | ".join(f"lr {r}" for r in rates) + " |",
         "|---|" + "---|" * len(rates)]
for f in freezes:
    lines.append(f"| {f} | " + " | ".join(f"{load(f'select_{f}_{r}')['med_cm']:.2f}" for r in rates) + " |")
lines += ["", chosen, "",
          "| family | method | n = 0 | " + " | ".join(f"n = {n}" for n in shots) + " |",
          "|---|---|---|" + "---|" * len(shots)]
results = {"chosen": chosen, "families": {}}
for fam in families:
    pre = load(f"pre_{fam}")["med_cm"]
    tuned = [load(f"tune_{fam}_{n}")["med_cm"] for n in shots]
    scratch = [load(f"scratch_{fam}_{n}")["med_cm"] for n in shots]
    results["families"][fam] = {"pretrained": pre, "shots": [int(n) for n in shots],
                                "fine_tuned": tuned, "scratch": scratch}
    lines.append(f"| {fam} | fine-tuned | {pre:.2f} | " + " | ".join(f"{v:.2f}" for v in tuned) + " |")
    lines.append(f"| {fam} | from scratch | - | " + " | ".join(f"{v:.2f}" for v in scratch) + " |")
text = "\n".join(lines) + "\n"
open(f"{out}/table.md", "w").write(text)
json.dump(results, open(f"{out}/results.json", "w"), indent=2)
print(text)

fig, ax = plt.subplots(figsize=(6, 4))
for fam, r in results["families"].items():
    n = r["shots"]
    line, = ax.plot([0] + n, [r["pretrained"]] + r["fine_tuned"], "o-", label=f"{fam}: fine-tuned")
    ax.plot(n, r["scratch"], "s--", color=line.get_color(), label=f"{fam}: from scratch")
ax.set_xscale("symlog", linthresh=10)
ax.set_xlabel("target strikes used")
ax.set_ylabel("MED on the held-out part (cm)")
ax.set_title("Few-shot fine-tuning of the transfer model")
ax.grid(True, alpha=0.3)
ax.legend(fontsize=8)
fig.tight_layout()
fig.savefig(f"{out}/fewshot.png", dpi=120)
