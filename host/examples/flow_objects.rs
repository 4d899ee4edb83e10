//! Per-object flow errors on image pairs dumped by `diag_loop --dump DIR`: for each pair
//! `S_T.a.png`, `S_T.b.png`, `S_T.gt.flo`, `S_T.labels.png`, the built-in flow's mean
//! endpoint error on each object, and a summary: objects whose mean EPE exceeds 5 px.
//!
//! `cargo run --release --example flow_objects -- DIR [--preset medium] [--per-object]
//! [KEY=VALUE...]`, keys (over the preset): `patch`, `stride`, `finest`, `coarsest`, `gd`,
//! `var`, `prop`, `anchor`, `anchor_levels`, `coarsest_prop` (the `FlowParams` fields
//! `patch_size_px`, `patch_stride_px`, `finest_level`, `coarsest_level`, `gd_iters`,
//! `variational_iters`, `spatial_propagation`, `coarse_anchor`, `coarse_anchor_levels`,
//! `coarsest_propagation`).

use std::collections::BTreeMap;

use riseg::flow::{DisFlow, FlowEstimator as _, FlowParams};
use riseg::io::image::{read_flo, read_gray16, read_rgb8};

fn main() -> anyhow::Result<()> {
    let args: Vec<String> = std::env::args().skip(1).collect();
    let dir = std::path::PathBuf::from(args.first().expect("DIR"));
    let preset = args
        .iter()
        .position(|a| a == "--preset")
        .and_then(|i| args.get(i + 1))
        .map_or("medium", String::as_str);
    let per_object = args.iter().any(|a| a == "--per-object");
    let mut params = FlowParams::preset(preset).expect("preset");
    for kv in args.iter().filter(|a| a.contains('=')) {
        let (k, v) = kv.split_once('=').expect("key=value");
        match k {
            "patch" => params.patch_size_px = v.parse()?,
            "stride" => params.patch_stride_px = v.parse()?,
            "finest" => params.finest_level = v.parse()?,
            "coarsest" => params.coarsest_level = Some(v.parse()?),
            "gd" => params.gd_iters = v.parse()?,
            "var" => params.variational_iters = v.parse()?,
            "prop" => params.spatial_propagation = v.parse()?,
            "anchor" => params.coarse_anchor = v.parse()?,
            "anchor_levels" => params.coarse_anchor_levels = v.parse()?,
            "coarsest_prop" => params.coarsest_propagation = v.parse()?,
            _ => anyhow::bail!("unknown key {k}"),
        }
    }
    let dis = DisFlow::new(params)?.with_threads(1)?;
    let mut stems: Vec<_> = std::fs::read_dir(&dir)?
        .filter_map(|e| {
            let n = e.ok()?.file_name().into_string().ok()?;
            n.strip_suffix(".a.png").map(str::to_owned)
        })
        .collect();
    stems.sort();
    let (mut objects, mut wrong, mut moved_wrong, mut sum, mut n) = (0, 0, 0, 0.0, 0u64);
    let mut ms = 0.0;
    for stem in &stems {
        let p = |s: &str| dir.join(format!("{stem}.{s}"));
        let (a, b) = (read_rgb8(&p("a.png"))?, read_rgb8(&p("b.png"))?);
        let gt = read_flo(&p("gt.flo"))?.with_unknown_as_nan();
        let labels = read_gray16(&p("labels.png"))?;
        let t0 = std::time::Instant::now();
        let f = dis.estimate(a.view(), b.view())?;
        ms += t0.elapsed().as_secs_f64() * 1e3;
        let mut err: BTreeMap<u16, (f64, u32, f64, [f64; 4])> = BTreeMap::new();
        for ((&l, e), g) in labels
            .as_slice()
            .iter()
            .zip(f.as_slice())
            .zip(gt.as_slice())
        {
            if l == 0 || !(g[0].is_finite() && g[1].is_finite()) {
                continue;
            }
            let d = f64::from(((e[0] - g[0]).powi(2) + (e[1] - g[1]).powi(2)).sqrt());
            let s = err.entry(l).or_default();
            s.0 += d;
            s.1 += 1;
            s.2 += f64::from(g[0].hypot(g[1]));
            s.3[0] += f64::from(e[0]);
            s.3[1] += f64::from(e[1]);
            s.3[2] += f64::from(g[0]);
            s.3[3] += f64::from(g[1]);
            sum += d;
            n += 1;
        }
        for (l, (s, k, m, q)) in err {
            let q = q.map(|x| x / f64::from(k));
            let (epe, mag) = (s / f64::from(k), m / f64::from(k));
            objects += 1;
            wrong += usize::from(epe > 5.0);
            moved_wrong += usize::from(epe > 5.0 && mag > 3.0);
            if per_object || epe > 5.0 {
                println!(
                    "{stem} object {l}: EPE {epe:.2} px, exact |flow| {mag:.1} px; mean flow ({:.1}, {:.1}) exact ({:.1}, {:.1})",
                    q[0], q[1], q[2], q[3]
                );
            }
        }
    }
    println!(
        "{} pairs, {objects} objects: {wrong} with EPE > 5 px ({moved_wrong} of them moved > 3 px); EPE on objects {:.3} px; {:.1} ms per pair",
        stems.len(),
        sum / n as f64,
        ms / stems.len() as f64
    );
    Ok(())
}
