function out = load_texplorer(target)
%LOAD_TEXPLORER Load a scan or the feature table of a texplorer export bundle (MATLAB or GNU Octave).
%
%   s = load_texplorer('scans/C6S1M1P2X1/granite-polished-01/granite-polished-01-001.mat')
%       All variables of the scan (v_ft, v_fs, v_tt, v_ts, a_fs, a_ts, r_fs, r_ts, f_frn, f_frt,
%       f_press, f_fold, alpha_f, t_cool, m, dB, meta; a scan may lack some) plus s.photos, a struct
%       with the full path of each photo:  imshow(imread(s.photos.I_disp))
%       Time axis of a channel:  t = (0:size(s.v_ts, 1) - 1)' / s.meta.fs.v_ts;
%
%   F = load_texplorer('path/to/bundle')
%       The feature table of features.mat: F.X (scans x features, NaN where undefined), F.columns
%       (feature names), F.labels (scans x 5: C S M P X), F.label, F.scan_id, F.sample_id.
%
%   Units and channels are described in README.md. Only load() is used, so nothing else is needed.

if exist(target, 'dir') == 7
  out = load(fullfile(target, 'features.mat'));
  return;
end
out = load(target);
folder = fileparts(target);
photos = {'I_disp', 'I_macro', 'I_illu'};
out.photos = struct();
for k = 1:numel(photos)
  if isfield(out, photos{k})
    out.photos.(photos{k}) = fullfile(folder, out.(photos{k}));
  end
end
end
