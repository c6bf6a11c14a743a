import pickle, time
from aidnav.analysis.noise_fit.fit import fit_allan
from aidnav.analysis.noise_fit.file_job import _warm_up
_warm_up()
ch = pickle.load(open("ch.pkl","rb"))
n = ch.n_samples; fs = ch.fs_hz
def run():
    for a in ch.axes: fit_allan(a.taus, a.adev, n, fs, axis=a.axis)
run()
b = []
for i in range(5):
    t=time.process_time(); run(); b.append(time.process_time()-t)
print("fit 6 axes min", round(min(b),3))
