//! Prints the native digests in the form `check.sh` compares: `input <hex> output <hex>`.

fn main() {
    println!(
        "input {:016x} output {:016x}",
        riseg_determinism::input_digest(),
        riseg_determinism::output_digest()
    );
}
