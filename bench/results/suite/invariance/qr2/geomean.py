import json, math, sys
d = json.load(open(sys.argv[1])); base = sys.argv[2]
R = d['regimes']; ms = list(next(iter(R.values()))['methods'])
print('| regime | ' + ' | '.join(ms) + ' |')
g = {m: [] for m in ms}
for r, v in R.items():
    b = v['methods'][base]['aee']
    row = []
    for m in ms:
        a = v['methods'][m]['aee']; g[m].append(a / b); row.append(f'{a:.4f} ({a/b:.3f})')
    print(f'| {r} | ' + ' | '.join(row) + ' |')
print('| geomean | ' + ' | '.join(f'{math.exp(sum(map(math.log,g[m]))/len(g[m])):.4f} / worst {max(g[m]):.3f}' for m in ms) + ' |')
