"""Table and JSON of scripts/fewshot_study.sh: OUT FREEZES RATES FAMILIES SHOTS (its figure:
scripts/plot.py fewshot OUT/results.json OUT/fewshot.png)."""
import json
import sys

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
