# Identification of each calibration model: XYΘ Models I-V (Sec. 4.5), nano models (Sec. 5.2).


def identify_inputs(w):
    c = CAMPAIGN[w.campaign]
    base = f"results/{w.campaign}"
    if c["robot"] != "xytheta":
        return {"run": f"{base}/runs/training.nc"}
    spec = c["models"][w.model]
    if "base" in spec:
        return {
            "base": f"{base}/models/{spec['base']}.nc",
            "residuals": f"{base}/runs/angle_residuals_{spec['base']}.nc",
        }
    inputs = {"run": f"{base}/runs/identification.nc"}
    if spec.get("position_table"):
        inputs["luts"] = f"{base}/luts/position.nc"
    return inputs


def identify_args(w, input):
    return " ".join(f"--{k} {v}" for k, v in input.items())


def identify_digest(w):
    c = CAMPAIGN[w.campaign]
    if c["robot"] != "xytheta":
        return digest([code_digest("identify"), c["model"]])
    return digest([code_digest("identify"), c["identification"], c["models"][w.model]])


rule identify:
    input:
        unpack(identify_inputs),
    output:
        model="results/{campaign}/models/{model}.nc",
    params:
        campaign=campaign_file,
        args=identify_args,
        digest=identify_digest,
    log:
        "results/{campaign}/logs/identify_{model}.log",
    benchmark:
        "results/{campaign}/benchmarks/identify_{model}.tsv"
    resources:
        mem_mb=2000,
    shell:
        "calflow identify --campaign {params.campaign} --model-name {wildcards.model}"
        " {params.args} --out {output.model} > {log} 2>&1"
