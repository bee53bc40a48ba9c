"""roughslip from Python: a depth sweep over an ensemble, its results as tables, a plot of
one's own, and one sample's fields exported for other tools (docs/guide/python.rst).

    pip install 'roughslip[tables,plot]'
    python python_tutorial.py

writes ``sweep.h5``, ``friction_coefficient.png``, ``sample0.nc`` and ``sample0_fz.png``
into the current folder. The documentation runs it cell by cell (the ``# %%`` lines, which
notebook editors read as cells) at every build and shows what each cell prints.
"""
# ruff: noqa: E402 (each cell imports what it uses, as notebook cells do)

# %% sweep
import roughslip
from roughslip.run.executor import run

config = roughslip.load_config(data={
    "title": "depth sweep, H = 0.8",
    "grid": {"n": 48, "pixel_size": 1.0},
    "material": {"E": 1.0, "nu": 0.3},
    "surface": {"kind": "self-affine", "hurst": 0.8, "rms_height": 1.0,
                "oversample": 2},
    "squeeze": {"depths": [0.25, 0.5, 1.0, 1.5, 2.0], "depth_unit": "rms"},
    "pull": {"enabled": True, "lam": 0.2},
    "ensemble": {"samples": 4, "seed": 4},
    "output": {"fields": ["contact", "stick", "fz", "fx", "gap"]},
})
summary = run(config, "sweep.h5", workers=1, overwrite=True)
print(f"{summary.computed} samples x {len(config.squeeze.depths)} depths "
      f"in {summary.seconds:.1f} s: {summary.path}")

# %% table
from roughslip.analysis.tables import to_dataframe

df = to_dataframe("sweep.h5")
print(df.shape)
columns = ["sample", "depth", "normal_force", "contact_area", "friction_force"]
print(df[columns].head(7))
print("H =", df.attrs["surface.hurst"], " lambda =", df.attrs["pull.lam"],
      " depths in", df.attrs["squeeze.depth_unit"])

# %% means
lam = df.attrs["pull.lam"]
df["mu"] = df["friction_force"] / (lam * df["normal_force"])
means = df.groupby("depth")[["contact_area", "mu"]].agg(["mean", "sem"])
print(means.round(4))

# %% xarray
from roughslip.analysis.tables import to_xarray

ds = to_xarray("sweep.h5")
print(ds["friction_force"])
mu = ds["friction_force"] / (ds.attrs["pull.lam"] * ds["normal_force"])
print("deepest state, per sample:", mu.sel(depth=2.0).round(3).values)

# %% plot
import matplotlib.pyplot as plt

fig, ax = plt.subplots(figsize=(6.5, 4.0), layout="constrained")
for _, rows in df.groupby("sample"):
    ax.plot(rows["contact_area"], rows["mu"], "-", color="0.75", lw=0.8)
m = df.groupby("depth")[["contact_area", "mu"]]
ax.errorbar(m.mean()["contact_area"], m.mean()["mu"], xerr=m.sem()["contact_area"],
            yerr=m.sem()["mu"], fmt="o-", color="C0", capsize=3,
            label=f"mean of {df['sample'].nunique()} samples, $\\pm$ standard error")
ax.plot([], [], "-", color="0.75", lw=0.8, label="each sample")
ax.set_xscale("log")
ax.set_xlabel("contact area (fraction of the grid)")
ax.set_ylabel(r"friction coefficient $F_{\rm friction} / (\lambda F_n)$")
n = df.attrs["grid.n"]
ax.set_title(f"{df.attrs['title']}, {n} x {n} pixels\n"
             f"{df.attrs['pull.slip_law']} law, $\\lambda$ = {lam}", fontsize=10)
ax.legend(loc="upper right", fontsize=9)
ax.grid(True, alpha=0.3)
fig.savefig("friction_coefficient.png", dpi=120)

# %% export
import numpy as np
import xarray as xr

from roughslip.analysis.tables import export_netcdf, sample_fields

export_netcdf("sweep.h5", "sample0.nc", sample=0)
back = xr.open_dataset("sample0.nc")
print(back[["contact", "stick", "fz", "fx"]])
fields = sample_fields("sweep.h5", sample=0)
same = all(np.array_equal(back[v].values, fields[v].values) for v in fields.data_vars)
print("equal to the run file's fields:", same)

# %% netcdf_plot
fig, ax = plt.subplots(figsize=(5.2, 4.0), layout="constrained")
deepest = back["fz"].isel(depth=-1)
deepest.plot(ax=ax, cmap="viridis")  # labels from the file: long_name, units if any
ax.set_title(f"sample 0, depth {float(deepest.depth):g} rms "
             "(a run without units: dimensionless)", fontsize=10)
ax.set_aspect("equal")
fig.savefig("sample0_fz.png", dpi=120)
back.close()
